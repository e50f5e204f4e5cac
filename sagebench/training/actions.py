"""The discrete actions that follow a reference path, derived as SAGE-3D's training data derives them
(`Code/data_pipeline/training_data_construction/generate_actions.py`, VLN-CE preset: 0.25 m, 15 degrees).

SAGE walks the path's sampled points (every turning point, every fifth point on straights: for sagebench's
reference paths, whose waypoints are exactly the corners of a shortcut polyline, that keeps every waypoint) and,
for each segment, first turns towards it, then moves forward by the distance accumulated so far in whole steps,
carrying the remainder to the next segment; a remainder over half a step at the end is one more MOVE_FORWARD, and
STOP ends the sequence. Where sagebench differs, so that the actions reach the goal of paths of any length:
the turn is rounded to the nearest whole turn from the heading the actions so far have left (SAGE truncates the
change between the points' own yaws and skips changes under 15 degrees, so its error accumulates), and SAGE's
caps (4 turns and 5 moves per segment, 50 actions per path) are not applied.
"""

from __future__ import annotations

import math

import numpy as np

from sagebench.navsim.actions import Action
from sagebench.settings.shared import ActionConfig


def path_actions(path: np.ndarray, start_yaw: float, config: ActionConfig = ActionConfig()) -> list[Action]:
    """Actions that walk `path` [K, >=2] (x, y, ... metres) from its first point, facing `start_yaw` (radians),
    ending with STOP (module docstring)."""
    path = np.asarray(path, dtype=np.float64)
    if path.ndim != 2 or path.shape[1] < 2 or not len(path):
        raise ValueError(f"path: expected [K, >=2] points, got {path.shape}")
    turn, step = math.radians(config.turn_deg), config.forward_step
    heading, carried = float(start_yaw), 0.0
    out: list[Action] = []
    for a, b in zip(path[:-1, :2], path[1:, :2]):
        length = float(np.hypot(*(b - a)))
        if length <= 1e-9:
            continue
        change = _wrap(math.atan2(b[1] - a[1], b[0] - a[0]) - heading)
        turns = round(abs(change) / turn)
        out += [Action.TURN_LEFT if change > 0 else Action.TURN_RIGHT] * turns
        heading += math.copysign(turns * turn, change)
        carried += length
        moves = int(carried // step)
        out += [Action.MOVE_FORWARD] * moves
        carried -= moves * step
    if carried > step / 2:
        out.append(Action.MOVE_FORWARD)
    return [*out, Action.STOP]


def _wrap(angle: float) -> float:
    """Angle in radians wrapped to [-pi, pi)."""
    return (angle + math.pi) % (2 * math.pi) - math.pi
