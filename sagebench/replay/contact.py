"""Contact along an agent's steps: the share of the positions along a step where the agent's cylinder comes within
CONTACT_DISTANCE (0.01 m) of a collider. Moving parallel to a wall at full speed loses no motion, so a c(t) read
from motion alone cannot see it; both the simulator's measured c(t) (sagebench.navsim) and evaluate's derived
c(t) (sagebench.evaluation.intensity) take the larger of their motion shortfall and this share. Paths planned
on the navigable map keep at least 0.02 m from the colliders, so following them costs nothing.
"""

from __future__ import annotations

import copy
from collections.abc import Sequence

import mujoco
import numpy as np

from sagebench.replay import CONTACT_DISTANCE
from sagebench.replay.physics import AGENT_GEOM, ReplayModel

SAMPLE_SPACING = 0.02  # m between the positions checked along a step


def contact_share(rm: ReplayModel, poses: Sequence[np.ndarray], *, distance: float = CONTACT_DISTANCE,
                  spacing: float = SAMPLE_SPACING, threads: int = 2) -> list[np.ndarray]:
    """[T_i] per pose sequence [T_i, >=2]: for each step (0 for row 0) the share of its positions where the agent's
    cylinder is within `distance` of a collider (module docstring). Every position is one state of one
    `mujoco.rollout` call whose contact sensor reads it."""
    return ContactProbe(rm, distance=distance, threads=threads).shares(poses, spacing=spacing)


class ContactProbe:
    """`contact_share` kept open for one model: the model copy with the agent's contact margin and the MjData
    of each thread are made once (about a millisecond each), not per call: the env checks every step with it."""

    def __init__(self, rm: ReplayModel, *, distance: float = CONTACT_DISTANCE, threads: int = 2):
        self.rm, self.distance, self.threads = rm, distance, max(1, threads)
        self.model = copy.copy(rm.model)
        g = self.model.geom(AGENT_GEOM).id
        self.model.geom_margin[g] = self.model.geom_gap[g] = distance  # contacts reported this far out, exact dist
        self._datas = [mujoco.MjData(self.model) for _ in range(self.threads)]
        full = mujoco.mjtState.mjSTATE_FULLPHYSICS
        self._rest = np.empty(mujoco.mj_stateSize(self.model, full))
        mujoco.mj_getState(self.model, self._datas[0], self._rest, full)
        self._xy_cols = mujoco.mj_stateSize(self.model, mujoco.mjtState.mjSTATE_TIME) + np.array(rm.qpos[:2])

    def shares(self, poses: Sequence[np.ndarray], *, spacing: float = SAMPLE_SPACING) -> list[np.ndarray]:
        """`contact_share` of these pose sequences."""
        from mujoco import rollout

        seqs = [np.asarray(p, dtype=np.float64)[:, :2] for p in poses]
        out = [np.zeros(len(xy)) for xy in seqs]
        steps = [(k, t) for k, xy in enumerate(seqs) for t in range(1, len(xy))]
        if not steps:
            return out
        a = np.concatenate([xy[:-1] for xy in seqs])  # every step's start and end, in `steps` order
        b = np.concatenate([xy[1:] for xy in seqs])
        xy, owner = _positions(a, b, spacing)
        model = self.model
        state = np.repeat(self._rest[None], len(xy), axis=0)
        state[:, self._xy_cols] = xy
        n = min(self.threads, len(xy))
        with rollout.Rollout(nthread=n if n > 1 else 0) as pool:
            _, sensor = pool.rollout(model, self._datas[:n], state, np.zeros((len(xy), 1, model.nu)), nstep=1,
                                     initial_warmstart=np.zeros((len(xy), model.nv)))
        found, dist = sensor[:, 0, self.rm.sensor], sensor[:, 0, self.rm.sensor + 1]
        touching = (found > 0) & (dist <= self.distance)
        share = np.bincount(owner, weights=touching, minlength=len(steps)) / np.bincount(owner, minlength=len(steps))
        for (k, t), v in zip(steps, share.tolist()):
            out[k][t] = v
        return out


def _positions(a: np.ndarray, b: np.ndarray, spacing: float) -> tuple[np.ndarray, np.ndarray]:
    """The positions checked along steps a -> b [S, 2]: n = ceil(length / spacing) + 1 evenly spaced, ends
    included (np.linspace's values), or the end alone for a step that does not move; and the step of each."""
    n = np.ceil(np.linalg.norm(b - a, axis=1) / spacing).astype(np.int64)
    count = np.where(n > 0, n + 1, 1)
    owner = np.repeat(np.arange(len(a)), count)
    j = np.arange(len(owner)) - np.repeat(np.cumsum(count) - count, count)  # index within its step
    nj = n[owner]
    t = np.where(j < nj, j * (1.0 / np.maximum(nj, 1)), 1.0)
    d = b - a
    xy = np.where((nj > 0)[:, None], a[owner] + d[owner] * t[:, None], b[owner])
    return xy, owner
