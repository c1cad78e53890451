"""Built-in robots plugins, one folder each."""
