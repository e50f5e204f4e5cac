"""VLN-CE's ground-truth files `{split}/{split}_gt.json.gz`, what its NDTW measure and recollect trainer read.

gzipped JSON {episode_id: {"locations": [[x, y, z], ...], "actions": [int, ...], "forward_steps": int}}:
`locations` the agent's positions along the teacher path in habitat's frame (the start, then each place a
move left it: turns and STOP add none, as NDTW records only positions that change), `actions` VLN-CE's action
ids (0 STOP, 1 MOVE_FORWARD, 2 TURN_LEFT, 3 TURN_RIGHT) ending with STOP, `forward_steps` the number of moves.
"""

from __future__ import annotations

import gzip
import json
from collections.abc import Mapping, Sequence

import numpy as np

from sagebench.vlnce.frame import to_habitat

MOVE_FORWARD = 1  # VLN-CE's (habitat's HabitatSimActions) id


def gt_entry(actions: Sequence[int], positions: np.ndarray) -> dict:
    """One episode's entry from its actions [T] and the world positions [T + 1, 3] they visit (start first)."""
    p = np.asarray(positions, dtype=np.float64)
    moved = np.concatenate([[True], np.any(p[1:] != p[:-1], axis=1)])
    return {"locations": [[float(v) for v in q] for q in to_habitat(p[moved])],
            "actions": [int(a) for a in actions], "forward_steps": int(sum(a == MOVE_FORWARD for a in actions))}


def gt_bytes(entries: Mapping[str, dict]) -> bytes:
    """The gzipped file of `entries` (episode_id -> gt_entry); byte-identical for the same entries."""
    text = json.dumps(dict(entries), sort_keys=True, separators=(",", ":")).encode()
    return gzip.compress(text, mtime=0)
