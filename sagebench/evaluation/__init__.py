"""Benchmark scoring: predictions (JSON Lines), collision intensity by replay, per-episode scores and means."""
