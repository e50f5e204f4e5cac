"""One module per CLI stage: each owns its inputs, outputs and atomic writes."""
