"""Benchmarks of sagebench's hot paths; `python -m benchmarks` runs them all and prints one table."""
