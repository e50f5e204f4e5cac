"""Observation profiles: what a policy sees, at which size and in which units, and which of it is privileged.

A profile names the images an agent gets and how depth is given; privileged observations (ground truth a robot
would not have on an R2R-style task) are never in a profile but `full`, and any other profile gets them only when
asked for by name (`privileged`):
- `pose`: the agent's world pose [x, y, z, yaw] (float64, m and rad);
- `gps_compass`: `gps` [2] float32, the agent's position relative to the episode's start in the start's frame
  ([forward, right], m), and `compass` [1] float32, its heading relative to the start's (rad in [-pi, pi)),
  as habitat's episodic GPS and compass sensors give them;
- `instance`: the instance-id image [H, W] int32 (ground-truth segmentation).

Profiles (sizes are width x height):
- `custom` (the default): the images of `observations` (rgb, depth) at width x height (224 x 224), depth in
  metres [H, W] float32, the instruction text and `collided` (a bump sensor: contact during the last action);
- `vlnce`: VLN-CE's R2R task (habitat-lab 0.1.7 defaults + VLN-CE's vlnce_task.yaml): rgb 224 x 224 uint8,
  depth 256 x 256 [H, W, 1] float32 normalised to [0, 1] over 0-10 m, the instruction text and its tokens
  (`instruction_tokens` [200] int64, word ids into the run's vocabulary, or the one given: EnvConfig.vocab and
  .tokenizer, sagebench.vlnce.vocab); no bump sensor;
- `sage`: what SAGE-Bench's evaluator gives its models (Code/benchmark/environment_evaluation of SAGE-3D):
  rgb 640 x 480 uint8 and depth [H, W] float32 metres clipped to [0, 6.5] (its RGB-D models' input), and the
  instruction text; no pose (its HTTP request sends current_yaw 0.0), no bump sensor;
- `full`: everything, privileged included: rgb, depth (m), instance at width x height, the instruction text and
  tokens, pose, gps, compass and collided.

The task (EnvConfig.task, docs/tasks.md) decides what the agent is told of its goal, in every profile: vln and
nogoal the instruction text (nogoal's is SAGE-Bench's exploration instruction, no goal); pointnav `pointgoal`
[rho, phi] float32 (habitat's PointGoalWithGPSCompassSensor: the goal from the agent's current pose, m and rad
counter-clockwise from its heading); objectnav `objectgoal`, the category's name; imagenav `imagegoal`, the rgb view
from the goal pose (when the profile renders rgb). The goal tasks get no instruction text or tokens.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from sagebench.episodes.tasks import pointgoal_polar
from sagebench.settings.rollout import PRIVILEGED, EnvConfig, check_profile
from sagebench.vlnce.vocab import TOKENS_PER_INSTRUCTION


@dataclass(frozen=True)
class DepthFormat:
    """How depth [H, W] metres becomes the observation: clipped to `clip` (m), then mapped to [0, 1] over it when
    `normalised`, with a trailing channel axis when `channel`."""

    clip: tuple[float, float] | None = None
    normalised: bool = False
    channel: bool = False

    def apply(self, depth: np.ndarray) -> np.ndarray:
        """[..., H, W] float32 m -> the observation (float32), one view or a batch."""
        d = depth.astype(np.float32)
        if self.clip is not None:
            lo, hi = self.clip
            d = np.clip(d, np.float32(lo), np.float32(hi))
            if self.normalised:
                d = (d - np.float32(lo)) / np.float32(hi - lo)
        return d[..., None] if self.channel else d

    def bounds(self) -> tuple[float, float]:
        """The values the observation can take."""
        if self.clip is None:
            return 0.0, math.inf
        return (0.0, 1.0) if self.normalised else self.clip

    def describe(self) -> str:
        if self.clip is None:
            return "m"
        lo, hi = self.clip
        return f"[0, 1] over {lo:g}-{hi:g} m" if self.normalised else f"m clipped to [{lo:g}, {hi:g}]"


@dataclass(frozen=True)
class Sensors:
    """A profile resolved: the observations one policy gets (module docstring)."""

    profile: str
    images: dict[str, tuple[int, int]]  # rgb / depth / instance -> (width, height) px
    depth: DepthFormat
    tokens: bool  # instruction_tokens
    bump: bool  # collided
    privileged: tuple[str, ...]  # of PRIVILEGED, in that order
    task: str = "vln"  # what the agent is told of its goal (module docstring)

    @property
    def keys(self) -> tuple[str, ...]:
        """Every key of the observation dict, in order."""
        keys = [k for k in ("rgb", "depth", "instance") if k in self.images]
        keys += [k for k in TASK_KEYS[self.task] if k != "imagegoal" or "rgb" in self.images]
        keys += ["instruction_tokens"] if self.tokens and self.task in ("vln", "nogoal") else []
        keys += ["pose"] if "pose" in self.privileged else []
        keys += ["gps", "compass"] if "gps_compass" in self.privileged else []
        return tuple(keys + (["collided"] if self.bump else []))

    def sizes(self) -> dict[tuple[int, int], tuple[str, ...]]:
        """The images grouped by size: one render per distinct size."""
        out: dict[tuple[int, int], list[str]] = {}
        for key, size in self.images.items():
            out.setdefault(size, []).append(key)
        return {size: tuple(keys) for size, keys in out.items()}

    def describe(self) -> dict:
        """Each observation key and what it holds (the rollout record's `observations`)."""
        what = {}
        for key in self.keys:
            if key in self.images:
                w, h = self.images[key]
                what[key] = {"rgb": f"{h}x{w}x3 uint8", "instance": f"{h}x{w} int32 instance ids",
                             "depth": f"{h}x{w}{'x1' if self.depth.channel else ''} float32 "
                                      f"{self.depth.describe()}"}[key]
            elif key == "imagegoal":
                w, h = self.images["rgb"]
                what[key] = f"{h}x{w}x3 uint8, the view from the goal pose"
            else:
                what[key] = DESCRIPTIONS[key]
        return {"profile": self.profile, "keys": what, "privileged": list(self.privileged)}


DESCRIPTIONS = {"instruction": "text",
                "instruction_tokens": f"{TOKENS_PER_INSTRUCTION} int64 word ids (the run's vocabulary, or --vocab's)",
                "pose": "[x, y, z, yaw] float64 world m, rad", "gps": "[forward, right] float32 m from the start",
                "compass": "[heading] float32 rad from the start's", "collided": "bool, contact in the last action",
                "pointgoal": "[rho, phi] float32 m, rad: the goal from the agent's pose",
                "objectgoal": "text, the goal category"}
TASK_KEYS = {"vln": ("instruction",), "nogoal": ("instruction",), "pointnav": ("pointgoal",),
             "objectnav": ("objectgoal",), "imagenav": ("imagegoal",)}

DEFAULT_SIZE = (224, 224)  # custom and full, width x height
VLNCE_RGB, VLNCE_DEPTH = (224, 224), (256, 256)  # VLN-CE's vlnce_task.yaml
VLNCE_DEPTH_FORMAT = DepthFormat(clip=(0.0, 10.0), normalised=True, channel=True)  # habitat-lab 0.1.7's depth sensor
SAGE_SIZE = (640, 480)  # SAGE-Bench's camera (its --low_res halves it)
SAGE_DEPTH_FORMAT = DepthFormat(clip=(0.0, 6.5))  # SAGE's RGB-D client clips depth to 6.5 m


def resolve(profile: str, *, width: int | None = None, height: int | None = None,
            observations: tuple[str, ...] | None = None, privileged: tuple[str, ...] = ()) -> Sensors:
    """The sensors of `profile` with the sizes and privileged observations asked for (None: the profile's);
    a combination the profile does not allow is a ProfileError saying why."""
    check_profile(profile, width=width, height=height, observations=observations)
    extra = tuple(k for k in PRIVILEGED if k in privileged)
    if profile == "vlnce":
        images = {"rgb": VLNCE_RGB, "depth": VLNCE_DEPTH}
        return Sensors("vlnce", _with_instance(images, VLNCE_RGB, extra), VLNCE_DEPTH_FORMAT, tokens=True,
                       bump=False, privileged=extra)
    if profile == "sage":
        size = (width or SAGE_SIZE[0], height or SAGE_SIZE[1])
        return Sensors("sage", _with_instance({"rgb": size, "depth": size}, size, extra), SAGE_DEPTH_FORMAT,
                       tokens=False, bump=False, privileged=extra)
    size = (width or DEFAULT_SIZE[0], height or DEFAULT_SIZE[1])
    if profile == "full":
        return Sensors("full", {"rgb": size, "depth": size, "instance": size}, DepthFormat(), tokens=True, bump=True,
                       privileged=PRIVILEGED)
    keys = ("rgb", "depth") if observations is None else tuple(dict.fromkeys(observations))
    return Sensors("custom", _with_instance({k: size for k in keys}, size, extra), DepthFormat(), tokens=False,
                   bump=True, privileged=extra)


def env_sensors(config: EnvConfig) -> Sensors:
    """The observations an environment's settings give a policy: its profile's, told of the goal as its task is."""
    sensors = resolve(config.profile, width=config.width, height=config.height, observations=config.observations,
                      privileged=config.privileged)
    return replace(sensors, task=config.task)


def _with_instance(images: dict[str, tuple[int, int]], size: tuple[int, int], privileged: tuple[str, ...]
                   ) -> dict[str, tuple[int, int]]:
    return {**images, "instance": size} if "instance" in privileged else images


def gps_compass(pose: np.ndarray, start: np.ndarray, start_yaw: float) -> tuple[np.ndarray, np.ndarray]:
    """habitat's episodic GPS [forward, right] m and compass [heading] rad (counter-clockwise positive) of the
    agent at `pose` [>=2 .., yaw last] relative to the episode's start [>=2] facing start_yaw (float32 each)."""
    d = np.asarray(pose[:2], dtype=np.float64) - np.asarray(start[:2], dtype=np.float64)
    c, s = math.cos(start_yaw), math.sin(start_yaw)
    forward, left = c * d[0] + s * d[1], -s * d[0] + c * d[1]
    heading = math.remainder(float(pose[-1]) - start_yaw, 2 * math.pi)
    return np.array([forward, -left], np.float32), np.array([heading], np.float32)


def pointgoal(pose: np.ndarray, goal: np.ndarray) -> np.ndarray:
    """habitat's PointGoalWithGPSCompassSensor for the agent at `pose` [>=2 .., yaw last]: [rho, phi] float32 of
    the goal [>=2] from its current pose (episodes/tasks.py's pointgoal_polar)."""
    return np.array(pointgoal_polar(float(pose[0]), float(pose[1]), float(pose[-1]), float(goal[0]), float(goal[1])),
                    np.float32)
