"""Several spacecraft in one study: passive (locked/shape) decomposition and the multi-body plant."""
