"""Literal execution of a Base_Action sentence: read its turns and distances back, walk them, check where it ends.

A Base_Action sentence is executable when an agent that starts at the trajectory's start pose, turns by each
stated angle (left counter-clockwise) and walks each stated distance straight ahead ends within the goal
radius and never crosses a blocked cell of the occupancy map. The generator chooses its rounding so that
this holds; `validate` checks it for every Base_Action row.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

import numpy as np

# "turn left about 90 degrees", "turn right 35 degrees", "turn around"; "walk forward about 2.5 metres", ...
_TURN = re.compile(r"\bturn (left|right) (?:about )?(\d+(?:\.\d+)?) degrees?\b|\bturn around\b")
_WALK = re.compile(r"\b(?:walk forward|go straight|move forward) (?:about )?(half a metre|1 metre|\d+(?:\.\d+)? metres)\b")
_CLAUSE = re.compile(f"{_TURN.pattern}|{_WALK.pattern}")


@dataclass(frozen=True)
class BlockedMap:
    """Cells the agent must not cross: [H, W] bool (occupancy != 0), index [row, col] = [y, x]."""

    blocked: np.ndarray  # [H, W] bool
    resolution: float  # metres per cell
    origin: tuple[float, float]  # world (x, y) of cell (0, 0)'s lower-left corner


@dataclass(frozen=True)
class Execution:
    """Where the literal execution went: the visited corners [K, 2] (start first), metres."""

    corners: np.ndarray  # [K, 2] float64
    end_error: float  # XY distance from the last corner to the goal, m
    crosses_blocked: bool

    def ok(self, goal_radius: float) -> bool:
        return self.end_error <= goal_radius and not self.crosses_blocked


def parse_actions(sentence: str) -> list[tuple[str, float]]:
    """The sentence's actions in order: ("turn", degrees, left positive) and ("forward", metres)."""
    out: list[tuple[str, float]] = []
    for m in _CLAUSE.finditer(sentence.lower()):
        side, degrees, distance = m.group(1), m.group(2), m.group(3)
        if distance is not None:
            value = 0.5 if distance == "half a metre" else 1.0 if distance == "1 metre" else float(distance.split()[0])
            out.append(("forward", value))
        elif side is None:
            out.append(("turn", 180.0))
        else:
            out.append(("turn", float(degrees) if side == "left" else -float(degrees)))
    return out


def execute(actions: list[tuple[str, float]], start_xy: np.ndarray, start_yaw: float) -> np.ndarray:
    """[K, 2] corners visited by turning and walking `actions` literally from (start_xy, start_yaw radians)."""
    pos = np.asarray(start_xy, dtype=np.float64)[:2].copy()
    heading = float(start_yaw)
    corners = [pos.copy()]
    for kind, amount in actions:
        if kind == "turn":
            heading += math.radians(amount)
        else:
            pos = pos + amount * np.array([math.cos(heading), math.sin(heading)])
            corners.append(pos.copy())
    return np.asarray(corners)


def crosses_blocked(corners: np.ndarray, blocked: BlockedMap) -> bool:
    """Whether the polyline `corners` [K, 2] passes over a blocked cell (or leaves the map), sampled every
    quarter cell."""
    pts = np.asarray(corners, dtype=np.float64)
    step = blocked.resolution / 4
    h, w = blocked.blocked.shape
    for a, b in zip(pts[:-1], pts[1:]):
        n = max(1, math.ceil(float(np.linalg.norm(b - a)) / step))
        s = a + np.linspace(0.0, 1.0, n + 1)[:, None] * (b - a)
        cols = np.floor((s[:, 0] - blocked.origin[0]) / blocked.resolution).astype(np.int64)
        rows = np.floor((s[:, 1] - blocked.origin[1]) / blocked.resolution).astype(np.int64)
        if ((rows < 0) | (rows >= h) | (cols < 0) | (cols >= w)).any() or blocked.blocked[rows, cols].any():
            return True
    return False


def execute_sentence(sentence: str, start_xy: np.ndarray, start_yaw: float, goal_xy: np.ndarray,
                     blocked: BlockedMap | None) -> Execution:
    """Execute a Base_Action sentence literally and measure its end error (and blocked crossings, given a map)."""
    corners = execute(parse_actions(sentence), start_xy, start_yaw)
    error = float(np.linalg.norm(corners[-1] - np.asarray(goal_xy, dtype=np.float64)[:2]))
    return Execution(corners, error, blocked is not None and crosses_blocked(corners, blocked))
