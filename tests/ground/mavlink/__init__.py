"""`fleet mavlink`."""
