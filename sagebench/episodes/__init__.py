"""Episodes: what gen-trajectories samples and writes (targets, rows, settings), the Parquet schema, shards,
splits, reading a run's episodes back, and the paths preview."""
