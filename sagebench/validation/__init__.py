"""Validation of a run's trajectories: verdicts from MuJoCo replays, appearance/physics spot checks, and the table
and report validate writes."""
