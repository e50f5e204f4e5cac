"""Policies that act on the closed-loop observations: the built-in baselines in VLN-CE's discrete actions.

A policy sees, per running episode, its observation dict and info (and at `begin`, the episodes themselves:
the baselines are privileged, the oracle reads the reference path and `straight` the goal).
- `oracle` walks the reference path's stations (oracle_targets): it turns towards the next one
  while the heading error exceeds half a turn step, else moves forward; a station within half a forward step
  of its last move (not only of where it ended) counts as passed, the path's end only where the agent then stands
  within a forward step of it; it stops after the end.
- `straight` turns towards the goal and moves forward; it stops within the goal radius (straight distance) or
  after stall_patience forward moves in a row without min_progress towards the goal.
- `random`: forward, or with random_turn_probability a turn of 15-90 degrees either way (as successive turn
  actions), 90-180 degrees after an action more than half blocked; stops after a number of actions drawn from
  [random_min_actions, random_max_actions]; each episode seeded by (seed, episode id).
- `stationary` stops at once: it never moves (every task must score it SR 0 and coverage ~0).
- `explorer` (navsim/explorer.py): the no-goal baseline, sweeping the navigable map's nearest unswept floor.
On a goal task (objectnav, pointnav, imagenav) the oracle stops as soon as it stands within its task's success
distance on foot (the simulator's distance_to_goal) and, past the reference path's end, walks on to the goal.
"""

from __future__ import annotations

import hashlib
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, model_validator

from sagebench.episodes.episode import Episode
from sagebench.metrics.on_foot import NavigableMap
from sagebench.navsim.actions import Action
from sagebench.settings.shared import ActionConfig
from sagebench.tasks.goals import GOAL_TASKS, success_distance

BUILT_IN = ("oracle", "straight", "random", "stationary", "explorer")


class PolicyConfig(BaseModel):
    """Settings of the baseline policies (defaults here, nowhere else)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    stall_patience: int = Field(default=4, ge=1, description="straight: forward moves without progress before it stops.")
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


def episode_rng(seed: int, episode_id: str) -> np.random.Generator:
    """A generator of its own for one episode: seeded by the run seed and a hash of the episode id."""
    digest = int.from_bytes(hashlib.sha256(episode_id.encode("utf-8")).digest()[:8], "little")
    return np.random.default_rng([seed, digest])


@dataclass(frozen=True)
class PolicyFailure:
    """In place of an action: the policy could not answer for this episode (why, one line); the rollout ends the
    episode as failed by the policy and goes on with the others."""

    reason: str


class Policy(Protocol):
    def begin(self, episodes: Sequence[Episode]) -> None:
        """A new batch of episodes (slot i is episodes[i])."""

    def act(self, slots: Sequence[int], observations: Sequence[dict], infos: Sequence[dict]) -> list:
        """One action (or PolicyFailure) per running slot."""


def heading_action(pose: np.ndarray, target: np.ndarray, turn: float) -> Action:
    """Turn towards `target` [2] while the heading error exceeds half a turn, else move forward."""
    err = math.remainder(math.atan2(target[1] - pose[1], target[0] - pose[0]) - pose[3], 2 * math.pi)
    if abs(err) > turn / 2:
        return Action.TURN_LEFT if err > 0 else Action.TURN_RIGHT
    return Action.MOVE_FORWARD


def _segment_distance(point: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    """Distance from `point` to the segment a-b (the agent's last move): a station the move passed by counts,
    not only one it ended near, since 15-degree headings can carry a 0.25 m move past a station by more than
    half a step on either side and the oracle would turn back and forth around it for ever."""
    ab = b - a
    t = float(np.clip(np.dot(point - a, ab) / max(float(np.dot(ab, ab)), 1e-24), 0.0, 1.0))
    return float(np.hypot(*(point - (a + t * ab))))


class Oracle:
    def __init__(self, actions: ActionConfig = ActionConfig()):
        self.actions = actions

    def begin(self, episodes: Sequence[Episode]) -> None:
        self.targets = [oracle_targets(e.reference_path, self.actions.forward_step)[1:] for e in episodes]
        self.reach = [success_distance(e) if e.task in GOAL_TASKS else None for e in episodes]
        self.goal = [np.asarray(e.goal[:2], dtype=np.float64) for e in episodes]
        self.next = [0] * len(episodes)
        self.last: list[np.ndarray | None] = [None] * len(episodes)

    def act(self, slots, observations, infos) -> list:
        out, reach, turn = [], self.actions.forward_step / 2, math.radians(self.actions.turn_deg)
        for i, obs, info in zip(slots, observations, infos):
            pose, t = obs["pose"], self.targets[i]
            moved_from = pose[:2] if self.last[i] is None else self.last[i]
            while self.next[i] < len(t) and _segment_distance(t[self.next[i]], moved_from, pose[:2]) <= reach:
                if (self.reach[i] is None and self.next[i] == len(t) - 1
                        and np.hypot(*(t[-1] - pose[:2])) > self.actions.forward_step):
                    break  # passing near the end is not enough: the oracle stops within a step of it
                self.next[i] += 1
            self.last[i] = np.array(pose[:2], dtype=np.float64)
            if self.reach[i] is not None and info["distance_to_goal"] <= self.reach[i]:
                out.append(Action.STOP)  # a goal task: within its success distance on foot
            elif self.next[i] < len(t):
                out.append(heading_action(pose, t[self.next[i]], turn))
            else:
                out.append(Action.STOP if self.reach[i] is None else heading_action(pose, self.goal[i], turn))
        return out


class Stationary:
    def begin(self, episodes: Sequence[Episode]) -> None:
        pass

    def act(self, slots, observations, infos) -> list:
        return [Action.STOP for _ in slots]


class Straight:
    def __init__(self, config: PolicyConfig = PolicyConfig(), actions: ActionConfig = ActionConfig()):
        self.config, self.actions = config, actions

    def begin(self, episodes: Sequence[Episode]) -> None:
        self.goal = [np.asarray(e.goal[:2], dtype=np.float64) for e in episodes]
        self.radius = [e.goal_radius for e in episodes]
        self.best = [math.inf] * len(episodes)
        self.idle = [0] * len(episodes)

    def act(self, slots, observations, infos) -> list:
        out = []
        for i, obs in zip(slots, observations):
            pose = obs["pose"]
            dist = float(np.hypot(*(self.goal[i] - pose[:2])))
            if dist <= self.radius[i] or self.idle[i] >= self.config.stall_patience:
                out.append(Action.STOP)
                continue
            a = heading_action(pose, self.goal[i], math.radians(self.actions.turn_deg))
            if a == Action.MOVE_FORWARD:
                improved = dist < self.best[i] - self.config.min_progress
                self.best[i] = dist if improved else self.best[i]
                self.idle[i] = 0 if improved else self.idle[i] + 1
            out.append(a)
        return out


class RandomWalk:
    def __init__(self, config: PolicyConfig = PolicyConfig(), actions: ActionConfig = ActionConfig(), *, seed: int = 0):
        self.config, self.actions, self.seed = config, actions, seed

    def begin(self, episodes: Sequence[Episode]) -> None:
        cfg = self.config
        self.rngs = [episode_rng(self.seed, e.episode_id) for e in episodes]
        self.budget = [int(g.integers(cfg.random_min_actions, cfg.random_max_actions + 1)) for g in self.rngs]
        self.taken = [0] * len(episodes)
        self.queue: list[list[Action]] = [[] for _ in episodes]

    def act(self, slots, observations, infos) -> list:
        out, step = [], math.radians(self.actions.turn_deg)
        for i, info in zip(slots, infos):
            if self.taken[i] >= self.budget[i]:
                out.append(Action.STOP)
                continue
            self.taken[i] += 1
            if not self.queue[i]:
                g = self.rngs[i]
                if info["collision_intensity"] > 0.5:
                    turn = g.uniform(math.pi / 2, math.pi)
                elif g.random() < self.config.random_turn_probability:
                    turn = g.uniform(math.pi / 12, math.pi / 2)
                else:
                    turn = 0.0
                side = Action.TURN_LEFT if g.random() < 0.5 else Action.TURN_RIGHT
                self.queue[i] = [side] * max(1, round(turn / step)) if turn else [Action.MOVE_FORWARD]
            out.append(self.queue[i].pop(0))
        return out


def built_in(name: str, *, seed: int = 0, config: PolicyConfig = PolicyConfig(),
             actions: ActionConfig = ActionConfig(), maps: Callable[[str], NavigableMap] | None = None) -> Policy:
    """The built-in policy called `name` (one of BUILT_IN); the explorer reads each scene's map from `maps`."""
    if name == "stationary":
        return Stationary()
    if name == "explorer":
        from sagebench.navsim.explorer import Explorer  # it steers as the oracle does (heading_action)

        if maps is None:
            raise ValueError("the explorer needs the scenes' navigable maps")
        return Explorer(maps, actions)
    if name == "oracle":
        return Oracle(actions)
    if name == "straight":
        return Straight(config, actions)
    if name == "random":
        return RandomWalk(config, actions, seed=seed)
    raise ValueError(f"unknown policy {name!r} (expected a URL or one of {', '.join(BUILT_IN)})")
