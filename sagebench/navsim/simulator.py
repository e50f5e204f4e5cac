"""Episodes run closed-loop: B episode slots of one run stepped together, one action each per step.

A step turns each running slot's action into a command (actions.py), moves the agents of each scene in one
MuJoCo call (motion.py), ends slots on STOP, on leaving the map, at a nogoal episode's budget (its actions,
sagebench/tasks/budget.py: `budget`, whatever the agent) or on the step limit, and renders every running slot's
view in one renderer call per scene (observe.py). Slots never influence each other: stepping
episodes together gives byte for byte what stepping them one at a time gives (tests/test_env.py).
Running metrics per slot: the distance on foot to the goal and success, both the task's (sagebench/tasks/goals.py;
NaN and never for nogoal, whose success is its coverage, scored by evaluate)
and c(t) of the last action: for an action that translates, the larger of the motion shortfall motion.py
measures and the share of the step (from the pose before to the pose after, every 2 cm) within 0.01 m of a
collider (sagebench.replay.contact, the same check evaluate derives c(t) with), so sliding along a wall at full
speed counts too; for a pure turn, only the share of the rotation contact blocked (motion.py): turning in place
beside a wall is not a collision. The reward is the step's progress on foot towards the goal.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from sagebench.evaluation.predictions import Prediction
from sagebench.episodes.episode import Episode
from sagebench.metrics.on_foot import GoalField, ViewpointField, distances_on_foot
from sagebench.navsim.actions import continuous_commands, discrete_commands
from sagebench.navsim.motion import Agents, wrap
from sagebench.navsim.observe import observe
from sagebench.navsim.profiles import Sensors, env_sensors, gps_compass, pointgoal
from sagebench.navsim.world import World, open_world, run_episodes, run_vocabulary
from sagebench.replay.contact import ContactProbe
from sagebench.settings.rollout import EnvConfig
from sagebench.tasks.budget import step_budget
from sagebench.tasks.goal_image import goal_image_file, read_goal_image
from sagebench.tasks.goals import goal_field, success_distance
from sagebench.vlnce.vocab import Vocabulary, read_vocabulary

POSE_DECIMALS = 6  # predictions are written to the micrometre / microradian
TRUNCATED = ("budget", "step_limit")  # outcomes that end an episode from outside (gymnasium's truncated)


@dataclass
class Slot:
    """One running (or finished) episode."""

    episode: Episode
    instruction: str
    world: World
    goal: GoalField | ViewpointField | None  # distances on foot to the episode's goal (None: nogoal, no goal)
    row: int  # the agent's row in its scene's Agents
    poses: list[tuple[float, float, float, float]]
    intensity: list[float]
    distance: float  # on foot to the goal now, m (NaN without a goal)
    budget: int | None = None  # nogoal: the actions it may take (sagebench/tasks/budget.py); None: no budget
    steps: int = 0
    stopped: bool = False
    outcome: str = ""  # "" while running, else stop / left_map / budget / step_limit / policy_failed
    collided: bool = False
    # the images of the slot's last view: rows of that step's render arrays (one array per image for all the
    # slots rendered together) while the slot runs, its own copies once it has ended (`detach`)
    last: dict[str, np.ndarray] = field(default_factory=dict)
    tokens: np.ndarray | None = None  # [TOKENS_PER_INSTRUCTION] int64 when the profile gives them
    goal_image: np.ndarray | None = None  # imagenav: the view from the goal pose, when the profile renders rgb

    @property
    def done(self) -> bool:
        return bool(self.outcome)

    @property
    def success(self) -> float:
        return float(self.goal is not None and self.stopped and self.distance <= success_distance(self.episode))

    def detach(self) -> None:
        """Copy the last view out of its step's arrays: an ended slot keeps it, and would keep them all alive."""
        self.last = {k: np.array(v) for k, v in self.last.items()}

    def prediction(self) -> Prediction:
        """The episode so far as a predictions.jsonl row, c(t) as the simulator measured it."""
        return Prediction(episode_id=self.episode.episode_id, poses=self.poses, stopped=self.stopped,
                          collision_intensity=self.intensity, intensity_source="simulator")


@dataclass(frozen=True)
class StepResult:
    observation: dict
    reward: float
    terminated: bool  # STOP or left the map
    truncated: bool  # a nogoal episode's budget or the step limit
    info: dict


class Simulator:
    """Episode slots over one run directory; scenes load on first use."""

    def __init__(self, run_dir: Path, config: EnvConfig = EnvConfig(), *, scene_id: str | None = None,
                 threads: int = 1):
        self.run_dir, self.config, self.threads = Path(run_dir), config, threads
        self.sensors = env_sensors(config)
        episodes, self.instructions = run_episodes(self.run_dir, scene_id)
        episodes = [e for e in episodes if e.task == config.task]  # each task runs alone, with its observations
        if config.success_distance is not None:
            episodes = [replace(e, goal_radius=config.success_distance) for e in episodes]
        self.vocabulary = vocabulary(self.run_dir, config) if self.sensors.tokens else None
        self.episodes = {e.episode_id: e for e in episodes}
        self.order = [e.episode_id for e in episodes]
        self._worlds: dict[str, World] = {}
        self.slots: list[Slot] = []
        self._agents: dict[str, Agents] = {}
        self._probes: dict[str, ContactProbe] = {}

    def world(self, scene_id: str) -> World:
        if scene_id not in self._worlds:
            c = self.config
            self._worlds[scene_id] = w = open_world(self.run_dir, scene_id, replay=c.replay,
                                                    images=tuple(self.sensors.images), renderer=c.renderer)
            self._probes[scene_id] = ContactProbe(w.model, threads=self.threads)
        return self._worlds[scene_id]

    def start(self, episode_ids: Sequence[str]) -> list[StepResult]:
        """Begin these episodes, one slot each, at their start poses."""
        unknown = [i for i in episode_ids if i not in self.episodes]
        if unknown:
            raise KeyError(f"no episode {unknown[0]!r} in {self.run_dir}")
        self.slots, self._agents = [], {}
        by_scene: dict[str, list[int]] = {}
        for i, eid in enumerate(episode_ids):
            e = self.episodes[eid]
            w = self.world(e.scene_id)
            rows = by_scene.setdefault(e.scene_id, [])
            pose = (float(e.start[0]), float(e.start[1]), w.model.floor_z, float(wrap(e.start_yaw)))
            text = self.instructions.get(eid, "")
            tokens = np.array(self.vocabulary.encode(text), np.int64) if self.vocabulary is not None else None
            goal = goal_field(w.navmap, e)
            self.slots.append(Slot(episode=e, instruction=text, world=w, goal=goal, row=len(rows),
                                   poses=[_rounded(pose)], intensity=[0.0], distance=_distance(goal, e.start),
                                   budget=step_budget(e, self.config.actions.control_interval), tokens=tokens,
                                   goal_image=self._goal_image(w, e)))
            rows.append(i)
        for sid, rows in by_scene.items():
            starts = np.array([[self.slots[i].episode.start[0], self.slots[i].episode.start[1],
                                self.slots[i].episode.start_yaw] for i in rows], dtype=np.float64)
            self._agents[sid] = Agents(self._worlds[sid].model, starts, threads=self.threads)
        self._render(range(len(self.slots)))
        return [self._result(s, 0.0, 0.0) for s in self.slots]

    def step(self, actions: Sequence) -> list[StepResult]:
        """One action per slot (ignored for finished slots); the slots' results in slot order."""
        if len(actions) != len(self.slots):
            raise ValueError(f"expected {len(self.slots)} actions (one per slot), got {len(actions)}")
        running = [i for i, s in enumerate(self.slots) if not s.done]
        c = self.config
        if running:
            if c.action_space == "discrete":
                v, omega, stop = discrete_commands(np.array([actions[i] for i in running]), c.actions)
            else:
                v, omega, stop = continuous_commands(np.array([actions[i] for i in running]), c.replay)
        before = {i: self.slots[i].distance for i in running}
        moving: dict[str, list[int]] = {}  # scene -> indices into running
        for k, i in enumerate(running):
            s = self.slots[i]
            if stop[k]:
                s.stopped, s.outcome, s.collided = True, "stop", False  # STOP takes no action: no new pose
            else:
                moving.setdefault(s.episode.scene_id, []).append(k)
        moved = []
        for sid, ks in moving.items():
            moved += self._move(sid, [running[k] for k in ks], np.asarray(v)[ks], np.asarray(omega)[ks])
        self._render(sorted(moved))
        for i in running:
            if self.slots[i].done:
                self.slots[i].detach()
        out = []
        for i, s in enumerate(self.slots):
            gained = before[i] - s.distance if i in before and np.isfinite(before[i] - s.distance) else 0.0
            out.append(self._result(s, gained, s.intensity[-1] if i in moved else 0.0))
        return out

    def _move(self, sid: str, rows: list[int], v: np.ndarray, omega: np.ndarray) -> list[int]:
        """Move these slots of one scene (commands v, omega [b]) and update their poses, c(t), distances on foot
        and outcomes, each kind in one call for all of them; the slots moved."""
        c, w = self.config, self._worlds[sid]
        slots = [self.slots[i] for i in rows]
        motion = self._agents[sid].move(np.array([s.row for s in slots]), v, omega, c.actions.control_interval,
                                        c.motion)
        steps = [np.array([s.poses[-1][:2], p[:2]]) for s, p in zip(slots, motion.pose)]
        near = np.array([share[1] for share in self._probes[sid].shares(steps)])
        translating = np.asarray(v, dtype=np.float64) > 0  # a pure turn counts only its own blocking
        intensity = np.where(translating, np.maximum(motion.intensity, near), motion.intensity)
        xy = motion.pose[:, :2]
        distance = _distances([s.goal for s in slots], xy)
        inside = w.inside(xy).tolist()
        yaw = wrap(motion.pose[:, 2]).tolist()
        for k, s in enumerate(slots):
            x, y = xy[k].tolist()
            s.poses.append(_rounded((x, y, w.model.floor_z, yaw[k])))
            s.intensity.append(round(float(intensity[k]), POSE_DECIMALS))
            s.collided = bool(motion.collided[k])
            s.steps += 1
            s.distance = distance[k]
            if not inside[k]:
                s.outcome = "left_map"
            elif s.budget is not None and s.steps >= s.budget:
                s.outcome = "budget"
            elif s.steps >= c.max_steps:
                s.outcome = "step_limit"
        return rows

    def check_goal_images(self, episode_ids: Sequence[str]) -> None:
        """Read every goal image file these episodes name (when the agent sees rgb): a DataError for one that is
        missing, not a PNG or not the rgb observation's size (sagebench.tasks.goal_image)."""
        if "rgb" in self.sensors.images:
            for eid in episode_ids:
                path = goal_image_file(self.run_dir, self.episodes[eid])
                if path is not None:
                    read_goal_image(path, self.sensors.images["rgb"], eid)

    def _goal_image(self, w: World, e) -> np.ndarray | None:
        """imagenav's goal at the profile's rgb size (None without rgb): the file the episode names, else the rgb
        view rendered from the goal pose."""
        if e.task != "imagenav" or "rgb" not in self.sensors.images or w.renderer is None:
            return None
        width, height = self.sensors.images["rgb"]
        path = goal_image_file(self.run_dir, e)
        if path is not None:
            return read_goal_image(path, (width, height), e.episode_id)
        pose = np.array([[e.goal[0], e.goal[1], w.model.floor_z, e.goal_yaw]], dtype=np.float64)
        c = self.config
        return observe(w.renderer, pose, ("rgb",), floor_z=w.model.floor_z, camera_height=c.camera.height,
                       hfov_deg=c.camera.hfov_deg, width=width, height=height)["rgb"][0].copy()

    def fail(self, slot: int) -> None:
        """End a running slot because its policy could not answer (it takes no further step)."""
        self.slots[slot].outcome = "policy_failed"
        self.slots[slot].detach()

    def _render(self, slots: Sequence[int]) -> None:
        """Each slot's images, one renderer call per scene and image size; depth as the profile gives it. A slot's
        images are rows of the call's arrays (views, no copy per slot)."""
        c, sensors = self.config, self.sensors
        by_scene: dict[str, list[int]] = {}
        for i in slots:
            by_scene.setdefault(self.slots[i].episode.scene_id, []).append(i)
        for sid, rows in by_scene.items():
            w = self._worlds[sid]
            poses = np.array([self.slots[i].poses[-1] for i in rows])
            images: dict[str, np.ndarray] = {}
            for (width, height), keys in sensors.sizes().items():
                images |= observe(w.renderer, poses, keys, floor_z=w.model.floor_z,
                                  camera_height=c.camera.height, hfov_deg=c.camera.hfov_deg, width=width,
                                  height=height)
            if "depth" in images:
                images["depth"] = sensors.depth.apply(images["depth"])
            for j, i in enumerate(rows):
                self.slots[i].last = {k: images[k][j] for k in sensors.keys if k in images}

    def _result(self, s: Slot, reward: float, c_t: float) -> StepResult:
        obs = observation(self.sensors, s)
        info = {"episode_id": s.episode.episode_id, "distance_to_goal": s.distance, "success": s.success,
                "collision_intensity": float(c_t), "steps": s.steps, "outcome": s.outcome or "running"}
        return StepResult(obs, float(reward), s.outcome in ("stop", "left_map"), s.outcome in TRUNCATED, info)


def vocabulary(run_dir: Path, config: EnvConfig) -> Vocabulary:
    """The vocabulary instruction_tokens index: the one given (--vocab), else the run's."""
    if config.vocab is not None:
        return read_vocabulary(config.vocab, config.tokenizer)
    return run_vocabulary(run_dir, config.tokenizer)


def observation(sensors: Sensors, s: Slot) -> dict:
    """The observation dict of a slot now: the profile's keys only (sagebench.navsim.profiles). Its images are the
    slot's rows of the last render's arrays, not copies (Slot.last)."""
    extra = {"instruction": s.instruction, "instruction_tokens": s.tokens, "collided": s.collided}
    if "pose" in sensors.privileged:
        extra["pose"] = np.array(s.poses[-1], dtype=np.float64)
    if "gps_compass" in sensors.privileged:
        extra["gps"], extra["compass"] = gps_compass(np.array(s.poses[-1]), s.episode.start, s.episode.start_yaw)
    e = s.episode
    if e.task == "pointnav":
        extra["pointgoal"] = pointgoal(np.array(s.poses[-1]), e.goal)
    elif e.task == "objectnav":
        extra["objectgoal"] = e.goal_category
    elif e.task == "imagenav":
        extra["imagegoal"] = s.goal_image
    return {k: s.last[k] if k in s.last else extra[k] for k in sensors.keys}


def _distance(goal: GoalField | ViewpointField | None, xy: np.ndarray) -> float:
    """Distance on foot from one point to the goal; NaN without a goal."""
    return math.nan if goal is None else float(goal.distance(np.asarray(xy)[None, :2])[0])


def _distances(goals: Sequence[GoalField | ViewpointField | None], xy: np.ndarray) -> list[float]:
    """Each agent's distance on foot to its own goal: the point goals of a scene in one call."""
    points = [k for k, g in enumerate(goals) if isinstance(g, GoalField)]
    out = [_distance(g, xy[k]) if not isinstance(g, GoalField) else math.nan for k, g in enumerate(goals)]
    if points:
        for k, d in zip(points, distances_on_foot([goals[k] for k in points], xy[points]).tolist()):
            out[k] = d
    return out


def _rounded(pose: tuple[float, float, float, float]) -> tuple[float, float, float, float]:
    return tuple(round(v, POSE_DECIMALS) for v in pose)  # type: ignore[return-value]
