"""Collision intensity c(t) per agent step: the fraction of a step's commanded motion that contact blocked.

A step commands a move from pose t-1 to pose t. c(t) = 0 when the agent ended within ARRIVAL_TOLERANCE
(0.05 m, one map cell) of pose t; otherwise c(t) = clip(1 - progress / |commanded|, 0, 1), progress being the
achieved XY displacement along the commanded direction, so being pushed sideways past a corner costs little
and being stopped dead costs 1. The allowance is the benchmark's spatial precision: reference paths are
planned on 0.05 m cells and validate accepts the brushes that leaves (a goal point a few centimetres inside
a collider's reach), so an agent that follows an accepted path scores ICP 0. Steps that command no
translation (shorter than the replay's waypoint tolerance: turns in place) have c(t) = 0, since contact never
twists the replay agent's heading.

`sagebench rollout` (and `baseline`, its alias) measure c(t) in the simulator. For predictions without
`collision_intensity`, `replay_intensity` replays every step of every episode on its own (a translation from the
predicted pose t-1 towards pose t, already facing it) in one `replay_batch`, so a step into a wall scores about 1 and a step
along free floor 0, whatever the steps before it did. Poses closer together than the allowance register a
wall they pass through by the steps that start inside it (the replay pushes the agent out: c = 1).

Replaying reached poses rarely blocks anything (an agent that scraped along a wall reached every pose it
reports), so evaluate also derives contact: `sagebench.replay.contact.contact_share` (the simulator's
measured c(t) uses it too) is the share of the positions along a step (its
start, its end and every SAMPLE_SPACING between) where the agent's cylinder comes within CONTACT_DISTANCE
(0.01 m) of a collider, and a derived c(t) is the larger of the two. A step that stays where it is counts its
one pose: an agent pressed against a wall scores 1 there — unless the step turned in place (its heading changed):
a turn counts only when the turn itself is blocked, which poses that show it completed rule out, so a pure turn
derives c(t) = 0 (the simulator measures a blocked turn: sagebench.navsim.motion). Paths planned on the navigable
map keep at least 0.02 m from the colliders (the demo's oracle: 0.020 m at its closest), so following them costs
nothing.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from sagebench.replay import CONTACT_DISTANCE

if TYPE_CHECKING:  # MuJoCo loads only when poses are replayed: predictions with c(t) need none
    from sagebench.replay.physics import ReplayModel

ICP_NOTE = ("measured: c(t) from sagebench rollout's simulator; self-reported: the agent's own; derived: evaluate "
            "replayed each step from pose t-1 towards pose t, c(t) = the larger of the share of the motion contact "
            f"blocked and the share of the step within {CONTACT_DISTANCE} m of a collider; a turn in place counts "
            "only when the turn itself is blocked")
ARRIVAL_TOLERANCE = 0.05  # m, one map cell: a step that ended this close to its target was not blocked (a brush)


def blocked_fraction(start: np.ndarray, target: np.ndarray, end: np.ndarray, *, min_step: float,
                     arrival: float = ARRIVAL_TOLERANCE) -> np.ndarray:
    """c per step [B] from the start, commanded target and achieved end positions [B, >=2] (metres): 0 for a
    step shorter than `min_step` (a turn) or one that ended within `arrival` of its target."""
    start, target, end = (np.asarray(a, dtype=np.float64)[:, :2] for a in (start, target, end))
    wanted = target - start
    length = np.linalg.norm(wanted, axis=1)
    blocked = (length >= min_step) & (np.linalg.norm(target - end, axis=1) > arrival)
    safe = np.where(blocked, length, 1.0)
    progress = ((end - start) * wanted).sum(axis=1) / safe
    return np.where(blocked, np.clip(1.0 - progress / safe, 0.0, 1.0), 0.0)


def replay_intensity(rm: ReplayModel, poses: Sequence[np.ndarray], *, threads: int = 2) -> list[np.ndarray]:
    """c(t) [T_i] for each pose sequence [T_i, >=2] by replaying each of its steps from the predicted pose."""
    tol = rm.config.waypoint_tolerance
    seqs = [np.asarray(p, dtype=np.float64)[:, :2] for p in poses]
    starts = np.concatenate([s[:-1] for s in seqs]) if seqs else np.zeros((0, 2))
    targets = np.concatenate([s[1:] for s in seqs]) if seqs else np.zeros((0, 2))
    d = targets - starts
    moving = np.flatnonzero(np.linalg.norm(d, axis=1) >= tol)
    yaw = np.arctan2(d[moving, 1], d[moving, 0])
    z = np.full(len(moving), rm.floor_z)
    paths = [np.array([[sx, sy, zz, a], [tx, ty, zz, a]]) for (sx, sy), (tx, ty), zz, a
             in zip(starts[moving], targets[moving], z, yaw)]
    from sagebench.replay.physics import replay_batch

    records = replay_batch(rm, paths, threads=threads)
    c = np.zeros(len(starts))
    if records:
        end = np.array([r.poses[-1, :2] for r in records])
        c[moving] = blocked_fraction(starts[moving], targets[moving], end, min_step=tol)
    bounds = np.cumsum([0] + [len(s) - 1 for s in seqs])
    return [np.concatenate([[0.0], c[bounds[i]: bounds[i + 1]]]) for i in range(len(seqs))]


def pure_turns(poses: np.ndarray, *, min_step: float) -> np.ndarray:
    """[T] bool for poses [T, 4] (x, y, z, yaw): the steps that turned in place (moved less than `min_step` m in XY,
    heading changed); row 0 is False."""
    p = np.asarray(poses, dtype=np.float64)
    still = np.linalg.norm(np.diff(p[:, :2], axis=0), axis=1) < min_step
    turned = np.abs(np.remainder(np.diff(p[:, 3]) + np.pi, 2 * np.pi) - np.pi) > 1e-9
    return np.concatenate([[False], still & turned])


def derive_intensity(rm: ReplayModel, poses: Sequence[np.ndarray], *, threads: int = 2) -> list[np.ndarray]:
    """Derived c(t) [T_i] per pose sequence [T_i, 4]: the larger of the replayed motion shortfall and the share of
    the step in contact, a pure turn's contact left out (module docstring)."""
    blocked = replay_intensity(rm, poses, threads=threads)
    from sagebench.replay.contact import contact_share

    near = contact_share(rm, poses, threads=threads)
    tol = rm.config.waypoint_tolerance
    return [np.maximum(b, np.where(pure_turns(p, min_step=tol), 0.0, n)) for p, b, n in zip(poses, blocked, near)]
