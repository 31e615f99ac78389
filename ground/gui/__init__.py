"""The Mission Manager in the browser: `ground-cli gui` (docs/gui.md)."""
