"""Replay: moving the agent through the scene (MuJoCo) and checking what it sees against the colliders."""
