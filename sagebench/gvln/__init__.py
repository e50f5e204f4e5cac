"""SAGE-3D's GVLN trajectory files (SAGE-Bench's episodes): sagebench episodes written as them and read from them."""
