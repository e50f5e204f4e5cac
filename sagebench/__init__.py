"""sagebench: artist scenes to an executable VLN benchmark."""
__version__ = "0.1.0"
