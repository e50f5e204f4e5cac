"""Scene model, loading and normalisation, and the built-in demo scene generator."""
