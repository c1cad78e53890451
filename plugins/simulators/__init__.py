"""Built-in simulators plugins, one folder each."""
