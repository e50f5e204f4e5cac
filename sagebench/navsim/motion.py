"""Agents moved for one control interval in the replay's MuJoCo model: contact stops them, c(t) is measured,
and an agent left penetrating a collider is put back to its last pose that was not (collision recovery).

The agent is the replay's (sagebench.replay.physics): a velocity-driven cylinder whose deadbeat drive reaches a
commanded speed in one physics step and whose force cap lets a collider stop it, so a move into a wall ends
against it at any speed the action space allows. An interval of S physics steps holds (v, omega); one more
step with no command probes the contact at the end pose (contact sensors read the pose a step starts from).

Per agent and interval, from the poses p_0 (start) .. p_S (end) and their contact readings:
- commanded motion: the sum over steps of v dt along the heading at that step (contact never turns the agent);
- c(t) = clip(1 - (achieved . commanded) / |commanded|^2, 0, 1) when the agent touched a collider at any
  p_k and was commanded to move, else 0 (docs/metrics.md's ICP, the simulator's own measurement);
- a pure turn (no translation commanded) is blocked only by the turn itself: c(t) = clip(1 - achieved / commanded
  rotation, 0, 1) when the agent touched a collider, else 0 (the agent's prism is not round, so a wall can stop
  its corners; standing near a wall while turning costs nothing);
- recovery: when p_S penetrates deeper than recovery_depth, the agent returns to the last p_k that does not,
  at rest (p_0 if none).

All B agents of one model advance in one `mujoco.rollout` call; every row is independent of the others.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import mujoco
import numpy as np

from sagebench.replay.physics import ReplayModel
from sagebench.settings.rollout import MotionConfig

_FULL = mujoco.mjtState.mjSTATE_FULLPHYSICS


@dataclass(frozen=True)
class Motion:
    """One interval of b agents."""

    pose: np.ndarray  # [b, 3] x, y, yaw (unwrapped) after it; the recovered pose where `recovered`
    collided: np.ndarray  # [b] bool, contact at any pose of the interval
    intensity: np.ndarray  # [b] c(t) in [0, 1]
    recovered: np.ndarray  # [b] bool
    penetration: np.ndarray  # [b] m, at the end pose before recovery


class Agents:
    """B agents' full MuJoCo states in one replay model, with their poses [B, 3] (x, y, yaw unwrapped)."""

    def __init__(self, rm: ReplayModel, poses: np.ndarray, *, threads: int = 1):
        self.rm, self.threads = rm, max(1, threads)
        m = rm.model
        self._qcols = mujoco.mj_stateSize(m, mujoco.mjtState.mjSTATE_TIME) + np.array(rm.qpos)
        self._vcols = mujoco.mj_stateSize(m, mujoco.mjtState.mjSTATE_TIME | mujoco.mjtState.mjSTATE_QPOS) + \
            np.arange(m.nv)
        self.state = np.zeros((0, mujoco.mj_stateSize(m, _FULL)))
        self._datas = [mujoco.MjData(m) for _ in range(self.threads)]
        self.place(np.asarray(poses, dtype=np.float64).reshape(-1, 3))

    def place(self, poses: np.ndarray, rows: np.ndarray | None = None) -> None:
        """Put agents (all, or `rows`) at poses [B, 3], at rest; a new row is appended when rows is None."""
        d = mujoco.MjData(self.rm.model)
        fresh = np.empty((len(poses), self.state.shape[1]))
        for i, p in enumerate(poses):
            mujoco.mj_resetData(self.rm.model, d)
            d.qpos[list(self.rm.qpos)] = p
            mujoco.mj_getState(self.rm.model, d, fresh[i], _FULL)
        if rows is None:
            self.state = fresh
        else:
            self.state[rows] = fresh

    @property
    def poses(self) -> np.ndarray:
        return self.state[:, self._qcols]

    def move(self, rows: np.ndarray, v: np.ndarray, omega: np.ndarray, interval: float,
             config: MotionConfig = MotionConfig()) -> Motion:
        """Hold (v [b] m/s, omega [b] rad/s) for `interval` seconds for the agents `rows` [b]."""
        from mujoco import rollout

        rows = np.asarray(rows, dtype=np.int64)
        m, dt = self.rm.model, self.rm.timestep
        steps = max(1, int(round(interval / dt)))
        b = len(rows)
        ctrl = np.zeros((b, steps + 1, m.nu))
        ctrl[:, :steps, 0] = np.asarray(v, dtype=np.float64)[:, None]
        ctrl[:, :steps, 2] = np.asarray(omega, dtype=np.float64)[:, None]
        start = self.state[rows].copy()
        n = min(self.threads, b)
        with rollout.Rollout(nthread=n if n > 1 else 0) as pool:
            out, sens = pool.rollout(m, self._datas[:n], start, ctrl, nstep=steps + 1,
                                     initial_warmstart=np.zeros((b, m.nv)))
        states = np.concatenate([start[:, None], out[:, :steps]], axis=1)  # [b, S + 1, nstate]: p_0 .. p_S
        pose = states[:, :, self._qcols]  # [b, S + 1, 3]
        found, dist = sens[:, :, self.rm.sensor], sens[:, :, self.rm.sensor + 1]
        depth = np.where(found > 0, np.maximum(0.0, -dist), 0.0)  # [b, S + 1]
        heading = np.stack([np.cos(pose[:, :steps, 2]), np.sin(pose[:, :steps, 2])], axis=2)
        commanded = (np.asarray(v, dtype=np.float64)[:, None, None] * dt * heading).sum(axis=1)
        achieved = pose[:, steps, :2] - pose[:, 0, :2]
        touched = (found > 0).any(axis=1)
        turn = np.asarray(omega, dtype=np.float64) * dt * steps
        intensity = blocked_share(commanded, achieved, turn, pose[:, steps, 2] - pose[:, 0, 2], touched)
        recover = depth[:, steps] > config.recovery_depth
        end = states[:, steps].copy()
        for i in np.flatnonzero(recover):
            ok = np.flatnonzero(depth[i, :steps] <= config.recovery_depth)
            end[i] = states[i, ok[-1] if len(ok) else 0]
            end[i, self._vcols] = 0.0
        self.state[rows] = end
        return Motion(pose=end[:, self._qcols], collided=touched, intensity=intensity, recovered=recover,
                      penetration=depth[:, steps])


def blocked_share(commanded: np.ndarray, achieved: np.ndarray, turn: np.ndarray, turned: np.ndarray,
                  touched: np.ndarray) -> np.ndarray:
    """c(t) [b] of intervals (module docstring) from the commanded and achieved XY motion [b, 2] (m), the commanded
    and achieved rotation [b] (rad) and whether the agent touched a collider [b]: the share of the commanded
    translation contact blocked, or for a pure turn the share of the rotation; 0 without contact."""
    norm2 = (commanded**2).sum(axis=1)
    moving = norm2 > 1e-18
    ratio = np.divide((achieved * commanded).sum(axis=1), norm2, out=np.ones(len(norm2)), where=moving)
    turning = ~moving & (np.abs(turn) > 1e-12)
    share = np.divide(turned, turn, out=np.ones(len(turn)), where=turning)
    shortfall = np.where(moving, 1.0 - ratio, np.where(turning, 1.0 - share, 0.0))
    return np.where(touched, np.clip(shortfall, 0.0, 1.0), 0.0)


def wrap(yaw: np.ndarray | float) -> np.ndarray:
    """Angles in [-pi, pi)."""
    return (np.asarray(yaw, dtype=np.float64) + math.pi) % (2 * math.pi) - math.pi
