"""Built-in optimizers plugins, one folder each."""
