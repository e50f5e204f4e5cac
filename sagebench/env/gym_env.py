"""gymnasium's API over the closed-loop simulator: `NavEnv` runs one episode at a time, `VectorNavEnv` several.

Constructing one sizes the process's renderer threads and makes idle ones wait passively (sagebench.threads).
reset(options={"episode_id": ID}) starts that episode; without one, episodes come in an order shuffled by the
reset seed (each once, then again). Observations: those of the config's profile (sagebench.navsim.profiles;
by default rgb [H, W, 3] uint8, depth [H, W] float32 m, instruction text and collided), pose, gps/compass and
instance ids only when asked for (EnvConfig.privileged) or in the `full` profile; every array is the caller's
own (a new one each step: editing it changes no later observation). info: episode_id (opaque, as a policy server
gets it: 16 hex digits, stable for the env's lifetime; the run's id when privileged observations were asked for or
in the `full` profile), distance_to_goal (on foot, m), success (SR so far), collision_intensity (c of this step),
steps, outcome. truncated: the step limit, or a nogoal episode's budget (outcome `budget`).
"""

from __future__ import annotations

import string
from collections.abc import Mapping, Sequence
from dataclasses import replace
from pathlib import Path

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from sagebench.navsim.actions import Action
from sagebench.navsim.opaque import OpaqueIds
from sagebench.navsim.profiles import env_sensors
from sagebench.navsim.simulator import Simulator, StepResult
from sagebench.settings.rollout import EnvConfig
from sagebench.threads import share_cores
from sagebench.vlnce.vocab import TOKENS_PER_INSTRUCTION

MAX_INSTRUCTION = 4096  # characters


def action_space(config: EnvConfig) -> spaces.Space:
    """Discrete(4) (STOP, MOVE_FORWARD, TURN_LEFT, TURN_RIGHT) or Box [v, omega, stop]."""
    if config.action_space == "discrete":
        return spaces.Discrete(len(Action))
    r = config.replay
    return spaces.Box(low=np.array([0.0, -r.max_turn_rate, 0.0], np.float32),
                      high=np.array([r.max_speed, r.max_turn_rate, 1.0], np.float32), dtype=np.float32)


def observation_space(config: EnvConfig, instructions: Sequence[str] = (), vocabulary: int = 0) -> spaces.Dict:
    """The observation dict's space (the profile's keys); the instruction's charset holds printable ASCII and every
    character used; token ids are below `vocabulary` (its size)."""
    sensors = env_sensors(config)
    size = {k: (h, w) for k, (w, h) in sensors.images.items()}
    low, high = sensors.depth.bounds()
    charset = sorted(set(string.printable) | {ch for text in instructions for ch in text})
    every = {
        "rgb": lambda: spaces.Box(0, 255, (*size["rgb"], 3), np.uint8),
        "depth": lambda: spaces.Box(low, high, (*size["depth"], 1) if sensors.depth.channel else size["depth"],
                                    np.float32),
        "instance": lambda: spaces.Box(0, np.iinfo(np.int32).max, size["instance"], np.int32),
        "instruction": lambda: spaces.Text(max_length=MAX_INSTRUCTION, min_length=0, charset="".join(charset)),
        "instruction_tokens": lambda: spaces.Box(0, max(vocabulary - 1, 0), (TOKENS_PER_INSTRUCTION,), np.int64),
        "pose": lambda: spaces.Box(-np.inf, np.inf, (4,), np.float64),
        "gps": lambda: spaces.Box(-np.inf, np.inf, (2,), np.float32),
        "compass": lambda: spaces.Box(-np.pi, np.pi, (1,), np.float32),
        "collided": lambda: spaces.Discrete(2),
        "pointgoal": lambda: spaces.Box(np.array([0.0, -np.pi], np.float32), np.array([np.inf, np.pi], np.float32)),
        "objectgoal": lambda: spaces.Text(max_length=MAX_INSTRUCTION, min_length=1, charset="".join(charset)),
        "imagegoal": lambda: spaces.Box(0, 255, (*size.get("rgb", (0, 0)), 3), np.uint8),
    }
    return spaces.Dict({k: every[k]() for k in sensors.keys})


def handed_out(sim: Simulator, opaque: OpaqueIds, r: StepResult) -> StepResult:
    """A step's result as the env hands it out (module docstring): arrays copied, the episode id opaque unless
    privileged."""
    obs = {k: np.array(v) if isinstance(v, np.ndarray) else v for k, v in r.observation.items()}
    info = r.info if sim.sensors.privileged else {**r.info, "episode_id": opaque(r.info["episode_id"])}
    return replace(r, observation=obs, info=info)


class NavEnv(gym.Env):
    """One episode of a run directory at a time (module docstring)."""

    metadata = {"render_modes": ["rgb_array"]}

    def __init__(self, run_dir: Path | str, config: EnvConfig | Mapping = EnvConfig(), *,
                 scene_id: str | None = None, render_mode: str | None = None, threads: int | None = None):
        share_cores(threads)  # an env process: renderer threads sized to `threads` cores, waiting passively
        config = EnvConfig.model_validate(config)  # a mapping too: gymnasium.make passes plain keyword values
        self.sim = Simulator(Path(run_dir), config, scene_id=scene_id)
        self.config, self.render_mode = config, render_mode
        self.metadata = {**self.metadata, "render_fps": 1.0 / config.actions.control_interval}  # a frame per action
        self.action_space = action_space(config)
        self.observation_space = observation_space(config, list(self.sim.instructions.values()),
                                                   len(self.sim.vocabulary.word_list) if self.sim.vocabulary else 0)
        self._queue: list[str] = []
        self._opaque = OpaqueIds()

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        if seed is not None:
            self._queue = []
        eid = (options or {}).get("episode_id")
        if eid is None:
            if not self._queue:
                self._queue = [self.sim.order[i] for i in self.np_random.permutation(len(self.sim.order))]
            eid = self._queue.pop(0)
        r = handed_out(self.sim, self._opaque, self.sim.start([eid])[0])
        return r.observation, r.info

    def step(self, action):
        if not self.sim.slots:
            raise RuntimeError("call reset() before step()")
        if self.sim.slots[0].done:
            raise RuntimeError("the episode has ended; call reset()")
        r = handed_out(self.sim, self._opaque, self.sim.step([action])[0])
        return r.observation, r.reward, r.terminated, r.truncated, r.info

    def render(self):
        if "rgb" not in self.sim.sensors.images:
            return None
        return self.sim.slots[0].last["rgb"] if self.sim.slots else None

    def prediction(self):
        """The current episode as a predictions.jsonl row (c(t) measured by the simulator)."""
        return self.sim.slots[0].prediction()


class VectorNavEnv:
    """Several episodes stepped together: physics in one MuJoCo call and rendering in one call per scene.

    Unlike gymnasium's vector envs it does not reset a finished episode: finished slots ignore their action and
    repeat their last result, so a batch of episodes runs until all are done (rollout's use).
    """

    def __init__(self, run_dir: Path, config: EnvConfig = EnvConfig(), *, scene_id: str | None = None,
                 threads: int = 2):
        share_cores(threads)
        self.sim = Simulator(run_dir, config, scene_id=scene_id, threads=threads)
        self.config = config
        self._opaque = OpaqueIds()
        self.single_action_space = action_space(config)
        self.single_observation_space = observation_space(
            config, list(self.sim.instructions.values()),
            len(self.sim.vocabulary.word_list) if self.sim.vocabulary else 0)

    def reset(self, episode_ids: Sequence[str]) -> tuple[list[dict], list[dict]]:
        results = [handed_out(self.sim, self._opaque, r) for r in self.sim.start(list(episode_ids))]
        return [r.observation for r in results], [r.info for r in results]

    def step(self, actions: Sequence) -> list[StepResult]:
        return [handed_out(self.sim, self._opaque, r) for r in self.sim.step(list(actions))]

    @property
    def done(self) -> list[bool]:
        return [s.done for s in self.sim.slots]

    def predictions(self):
        return [s.prediction() for s in self.sim.slots]
