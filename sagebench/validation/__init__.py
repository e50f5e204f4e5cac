"""Validation of a run's trajectories: verdicts from MuJoCo replays, and appearance/physics spot checks."""
