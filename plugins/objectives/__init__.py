"""Built-in objectives plugins, one folder each."""
