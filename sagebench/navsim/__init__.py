"""Closed-loop navigation: actions, agents moved by MuJoCo with collision recovery, rendered observations, episodes."""
