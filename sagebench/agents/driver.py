"""Run a policy in MuJoCo: every episode's agent takes one action at a time, all episodes batched per action.

An action is a target pose (x, y, yaw): a target farther than the replay's waypoint tolerance is a move (the
replay controller turns towards it, then drives straight at it until it arrives, stalls against a collider or
runs out of time), a nearer one a turn in place to the target yaw. The agent's pose after each action is one
row of its prediction, and the action's collision intensity c(t) is measured as it happens
(`sagebench.evaluation.intensity.blocked_fraction`). Every action of every episode still running is one path
of one `replay_batch`, so batching never changes an episode's result.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Protocol

import numpy as np

from sagebench.evaluation.intensity import blocked_fraction
from sagebench.evaluation.predictions import Prediction
from sagebench.evaluation.scoring import Episode
from sagebench.replay.physics import ReplayModel, replay_batch

POSE_DECIMALS = 6  # predictions are written to the micrometre / microradian


class Policy(Protocol):
    """Chooses the next action of the episodes still running."""

    def act(self, rows: np.ndarray, pose: np.ndarray, last_intensity: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """rows [B] episode indices, pose [B, 3] (x, y, yaw) now, last_intensity [B] c of the previous action.

        Returns target [B, 3] (x, y, yaw) and stop [B] bool (stop: end the episode now, no action).
        """
        ...


def drive(rm: ReplayModel, episodes: Sequence[Episode], policy: Policy, *, max_actions: int,
          threads: int = 2) -> list[Prediction]:
    """One prediction per episode: the agent starts at the episode's start pose and acts until the policy stops
    it (`stopped` True) or it has taken `max_actions` actions (`stopped` False)."""
    n = len(episodes)
    pose = np.array([[e.start[0], e.start[1], e.start_yaw] for e in episodes], dtype=np.float64).reshape(n, 3)
    trail: list[list[np.ndarray]] = [[p.copy()] for p in pose]
    intensity: list[list[float]] = [[0.0] for _ in range(n)]
    last = np.zeros(n)
    stopped = np.zeros(n, dtype=bool)
    active = np.arange(n)
    tol = rm.config.waypoint_tolerance
    for step in range(max_actions + 1):
        if not len(active):
            break
        target, stop = policy.act(active, pose[active], last[active])
        stopped[active[stop]] = True
        active, target = active[~stop], np.asarray(target, dtype=np.float64)[~stop]
        if not len(active) or step == max_actions:
            break
        z = rm.floor_z
        paths = [np.array([[x, y, z, a], [tx, ty, z, ta]]) for (x, y, a), (tx, ty, ta) in zip(pose[active], target)]
        records = replay_batch(rm, paths, threads=threads)
        end = np.array([[r.poses[-1, 0], r.poses[-1, 1], r.poses[-1, 3]] for r in records])
        c = blocked_fraction(pose[active], target, end, min_step=tol)
        pose[active], last[active] = end, c
        for row, p, ci in zip(active, end, c):
            trail[row].append(p)
            intensity[row].append(float(ci))
    out = []
    for e, rows, c, s in zip(episodes, trail, intensity, stopped):
        xyyaw = np.round(np.array(rows), POSE_DECIMALS)
        poses = [(float(x), float(y), round(rm.floor_z, POSE_DECIMALS), float(a)) for x, y, a in xyyaw]
        out.append(Prediction(episode_id=e.episode_id, poses=poses, stopped=bool(s),
                              collision_intensity=[round(v, POSE_DECIMALS) for v in c]))
    return out
