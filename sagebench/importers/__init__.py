"""Importers of other scene and episode formats (InteriorGS scenes, SAGE's GVLN episodes) into sagebench's own."""
