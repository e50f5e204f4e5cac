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

from sagebench.replay.physics import AGENT_GEOM, ReplayModel

CONTACT_DISTANCE = 0.01  # m: an agent cylinder this close to a collider touches it
SAMPLE_SPACING = 0.02  # m between the positions checked along a step


def contact_share(rm: ReplayModel, poses: Sequence[np.ndarray], *, distance: float = CONTACT_DISTANCE,
                  spacing: float = SAMPLE_SPACING, threads: int = 2) -> list[np.ndarray]:
    """[T_i] per pose sequence [T_i, >=2]: for each step (0 for row 0) the share of its positions where the agent's
    cylinder is within `distance` of a collider (module docstring). Every position is one state of one
    `mujoco.rollout` call whose contact sensor reads it."""
    from mujoco import rollout

    model = copy.copy(rm.model)
    g = model.geom(AGENT_GEOM).id
    model.geom_margin[g] = model.geom_gap[g] = distance  # contacts reported (at least) this far out, exact dist
    seqs = [np.asarray(p, dtype=np.float64)[:, :2] for p in poses]
    points, owner = [], []  # every position checked, and the (sequence, step) it belongs to
    for k, xy in enumerate(seqs):
        for t in range(1, len(xy)):
            n = int(np.ceil(np.linalg.norm(xy[t] - xy[t - 1]) / spacing))
            points.append(xy[t - 1] + (xy[t] - xy[t - 1]) * np.linspace(0.0, 1.0, n + 1)[:, None] if n else xy[t][None])
            owner += [(k, t)] * len(points[-1])
    out = [np.zeros(len(xy)) for xy in seqs]
    if not points:
        return out
    xy = np.concatenate(points)
    full = mujoco.mjtState.mjSTATE_FULLPHYSICS
    data = mujoco.MjData(model)
    state = np.empty((len(xy), mujoco.mj_stateSize(model, full)))
    mujoco.mj_getState(model, data, state[0], full)
    state[:] = state[0]
    state[:, mujoco.mj_stateSize(model, mujoco.mjtState.mjSTATE_TIME) + np.array(rm.qpos[:2])] = xy
    n = max(1, min(threads, len(xy)))
    with rollout.Rollout(nthread=n if n > 1 else 0) as pool:
        _, sensor = pool.rollout(model, [mujoco.MjData(model) for _ in range(n)], state,
                                 np.zeros((len(xy), 1, model.nu)), nstep=1)
    found, dist = sensor[:, 0, rm.sensor], sensor[:, 0, rm.sensor + 1]
    touching = (found > 0) & (dist <= distance)
    sums: dict[tuple[int, int], list[float]] = {}
    for key, hit in zip(owner, touching):
        sums.setdefault(key, []).append(float(hit))
    for (k, t), hits in sums.items():
        out[k][t] = float(np.mean(hits))
    return out
