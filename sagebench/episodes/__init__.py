"""Episode rows: the Parquet schema of DESIGN.md, the shard writer and the paths preview."""
