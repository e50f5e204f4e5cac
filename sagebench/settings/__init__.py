"""Every command's settings, each declared once: one module per command (and shared.py for what several share),
each setting a field with its default, bounds, description and command-line option (docs/development.md)."""
