"""The three baseline policies: oracle (follows the reference path), straight (heads for the goal), random.

- `oracle` walks the reference polyline in moves of at most step_length: its targets are the points every
  step_length along the path (the stations nDTW and CSR resample the reference to) plus every corner, and it
  stops after the last. It shows what a perfect agent scores: SR 1, SPL and nDTW about 1, CSR 1, ICP 0.
- `straight` knows the goal but not the map: it turns towards the goal and moves at it in steps of
  step_length, sliding along or pushing into whatever is in the way. It stops when within goal_radius of the
  goal, or when stall_patience actions in a row brought it no min_progress nearer (stuck).
- `random` wanders: forward by step_length, or with random_turn_probability a turn in place of 15-90 degrees
  either way, and a turn of 90-180 degrees after an action that was more than half blocked. It stops after a
  number of actions drawn uniformly from [random_min_actions, random_max_actions]. Each episode has its own
  generator, seeded by (seed, episode id), so an episode's walk does not depend on which others run with it.
"""

from __future__ import annotations

import hashlib
import math
from collections.abc import Sequence

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, model_validator

from sagebench.evaluation.scoring import Episode

AGENTS = ("oracle", "straight", "random")


class PolicyConfig(BaseModel):
    """Settings of the baseline policies (defaults here, nowhere else)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    step_length: float = Field(default=0.25, gt=0, description="Longest move per action, m (VLN-CE's forward step).")
    stall_patience: int = Field(default=4, ge=1, description="straight: actions without progress before it stops.")
    min_progress: float = Field(default=0.05, ge=0, description="straight: nearer to the goal than this counts as progress, m.")
    random_turn_probability: float = Field(default=0.25, ge=0, le=1, description="random: chance an action is a turn.")
    random_min_actions: int = Field(default=10, ge=0, description="random: fewest actions before it stops.")
    random_max_actions: int = Field(default=150, ge=0, description="random: most actions before it stops.")

    @model_validator(mode="after")
    def _range(self) -> PolicyConfig:
        if self.random_max_actions < self.random_min_actions:
            raise ValueError("random_max_actions must be at least random_min_actions")
        return self


def oracle_targets(reference_path: np.ndarray, step_length: float, *, merge: float = 0.05) -> np.ndarray:
    """[K, 2] points along the XY polyline of `reference_path` [M, >=2]: its start, every step_length of arc
    length, every corner and the end; a station closer than `merge` (m) to a corner gives way to the corner."""
    p = np.asarray(reference_path, dtype=np.float64)[:, :2]
    keep = np.concatenate([[True], np.linalg.norm(np.diff(p, axis=0), axis=1) > 0])
    p = p[keep]  # two waypoints at one spot (a turn) are one point here
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(p, axis=0), axis=1))])
    stations = np.arange(0.0, s[-1], step_length)
    near_corner = np.abs(stations[:, None] - s[None, :]).min(axis=1) < merge if len(stations) else np.zeros(0, bool)
    arc = np.union1d(stations[~near_corner], s)
    return np.column_stack([np.interp(arc, s, p[:, 0]), np.interp(arc, s, p[:, 1])])


class Oracle:
    """Moves to the next point of `oracle_targets` each action; stops after the last."""

    def __init__(self, episodes: Sequence[Episode], config: PolicyConfig):
        self.targets = [oracle_targets(e.reference_path, config.step_length) for e in episodes]
        self.next = np.ones(len(episodes), dtype=np.int64)

    def act(self, rows: np.ndarray, pose: np.ndarray, last_intensity: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        target, stop = np.array(pose, dtype=np.float64), np.zeros(len(rows), dtype=bool)
        for i, r in enumerate(rows):
            if self.next[r] >= len(self.targets[r]):
                stop[i] = True
            else:
                target[i, :2] = self.targets[r][self.next[r]]
                self.next[r] += 1
        return target, stop


class Straight:
    """Moves step_length straight at the goal each action (module docstring)."""

    def __init__(self, episodes: Sequence[Episode], config: PolicyConfig):
        self.config = config
        self.goal = np.array([e.goal[:2] for e in episodes], dtype=np.float64).reshape(-1, 2)
        self.radius = np.array([e.goal_radius for e in episodes], dtype=np.float64)
        self.best = np.full(len(episodes), np.inf)
        self.since_best = np.zeros(len(episodes), dtype=np.int64)

    def act(self, rows: np.ndarray, pose: np.ndarray, last_intensity: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        d = self.goal[rows] - pose[:, :2]
        dist = np.linalg.norm(d, axis=1)
        improved = dist < self.best[rows] - self.config.min_progress
        self.best[rows] = np.where(improved, dist, self.best[rows])
        self.since_best[rows] = np.where(improved, 0, self.since_best[rows] + 1)
        stop = (dist <= self.radius[rows]) | (self.since_best[rows] >= self.config.stall_patience)
        move = np.minimum(self.config.step_length, dist) / np.maximum(dist, 1e-12)
        target = np.column_stack([pose[:, :2] + d * move[:, None], np.arctan2(d[:, 1], d[:, 0])])
        return target, stop


def episode_rng(seed: int, episode_id: str) -> np.random.Generator:
    """A generator of its own for one episode: seeded by the run seed and a hash of the episode id."""
    digest = int.from_bytes(hashlib.sha256(episode_id.encode("utf-8")).digest()[:8], "little")
    return np.random.default_rng([seed, digest])


class RandomWalk:
    """Forward moves and random turns, seeded per episode (module docstring)."""

    def __init__(self, episodes: Sequence[Episode], config: PolicyConfig, *, seed: int):
        self.config = config
        self.rngs = [episode_rng(seed, e.episode_id) for e in episodes]
        self.budget = np.array([g.integers(config.random_min_actions, config.random_max_actions + 1)
                                for g in self.rngs], dtype=np.int64)
        self.taken = np.zeros(len(episodes), dtype=np.int64)

    def act(self, rows: np.ndarray, pose: np.ndarray, last_intensity: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        cfg = self.config
        target, stop = np.array(pose, dtype=np.float64), np.zeros(len(rows), dtype=bool)
        for i, r in enumerate(rows):
            if self.taken[r] >= self.budget[r]:
                stop[i] = True
                continue
            g = self.rngs[r]
            self.taken[r] += 1
            if last_intensity[i] > 0.5:
                turn = g.uniform(math.pi / 2, math.pi)
            elif g.random() < cfg.random_turn_probability:
                turn = g.uniform(math.pi / 12, math.pi / 2)
            else:
                target[i, :2] += cfg.step_length * np.array([math.cos(pose[i, 2]), math.sin(pose[i, 2])])
                continue
            target[i, 2] = math.remainder(pose[i, 2] + (turn if g.random() < 0.5 else -turn), 2 * math.pi)
        return target, stop


def make_policy(name: str, episodes: Sequence[Episode], config: PolicyConfig, *, seed: int):
    """The policy called `name` (one of AGENTS) for these episodes."""
    if name == "oracle":
        return Oracle(episodes, config)
    if name == "straight":
        return Straight(episodes, config)
    if name == "random":
        return RandomWalk(episodes, config, seed=seed)
    raise ValueError(f"unknown agent {name!r} (expected one of {', '.join(AGENTS)})")
