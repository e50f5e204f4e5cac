"""Baseline agents (oracle, straight, random) that drive the replay agent in a scene's MuJoCo model."""
