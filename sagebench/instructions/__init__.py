"""Instructions for trajectories: the generators of each `--instructions` mode (registry.py) and what they share."""
