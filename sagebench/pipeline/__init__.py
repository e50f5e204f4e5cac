"""Multi-scene runs: run config, per-stage content-addressed skipping, executors, manifests."""
