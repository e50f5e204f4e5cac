"""Replay: moving the agent through the scene (MuJoCo) and checking what it sees against the colliders.

CONTACT_DISTANCE is here, not in contact.py, so that what only quotes it (evaluate's note on c(t)) loads no MuJoCo.
"""

CONTACT_DISTANCE = 0.01  # m: an agent cylinder this close to a collider touches it
