"""Replay: seeing the scene from the agent (CPU splat renderer) and moving through it (MuJoCo)."""
