"""Training data from a run: discrete actions along the reference paths, executed and rendered, as shards."""
