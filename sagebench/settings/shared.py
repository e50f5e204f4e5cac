"""Settings that several commands share: the agent's body and camera, the renderer, the MuJoCo replay, the
discrete actions, the metrics' constants, the split names and how instructions become tokens (defaults here,
nowhere else)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationInfo, field_validator

from sagebench.settings.option import Option

SPLITS = ("train", "val_seen", "val_unseen", "test", "trajectory_unseen", "instruction_unseen")
Split = Literal["train", "val_seen", "val_unseen", "test", "trajectory_unseen", "instruction_unseen"]
# SAGE-Bench's test splits by the split that holds them here (episodes/splits.py)
SAGE_SPLITS = {"Scene-Unseen": "test", "Trajectory-Unseen": "trajectory_unseen", "Instruction-Unseen": "instruction_unseen"}
# SAGE-Bench's task family (docs/tasks.md): instruction following, exploration without a goal, and the three goal
# tasks of its evaluator; "vln" is every episode written before tasks existed
TASKS = ("vln", "nogoal", "objectnav", "pointnav", "imagenav")
Task = Literal["vln", "nogoal", "objectnav", "pointnav", "imagenav"]
RendererChoice = Literal["auto", "cpu", "gsplat"]
RENDERER = ("Renderer: cpu (the reference), gsplat (CUDA GPU, pip install 'sagebench[gpu]') or auto (gsplat when it "
            "can run here).")

Tokenizer = Literal["sagebench", "habitat"]  # how instruction_tokens split an instruction (vlnce/vocab.py)
# instruction_tokens of rollout's closed loop and of export-vlnce's dataset: one declaration for both commands
TokenizerSetting = Annotated[Tokenizer, Option("--tokenizer"), Field(
    default="sagebench", description="How instruction_tokens split an instruction: sagebench (words; punctuation "
                                     "dropped) or habitat (habitat-lab's tokenize, R2R-CE's: punctuation kept as "
                                     "tokens, ',' and '?' removed); vlnce/vocab.py.")]
VocabSetting = Annotated[Path | None, Option("--vocab"), Field(
    default=None, description="instruction_tokens index this vocabulary (a pretrained VLN-CE model's): VLN-CE's "
                              "format, an R2R-CE dataset file (.json or .json.gz) or its instruction_vocab "
                              "(word_list or itos); words not in it are <unk>, counted (default: the run's "
                              "vocabulary).")]


class AgentConfig(BaseModel):
    """The robot's body, declared here and nowhere else (metres above the floor): a cylinder of `radius` from
    `clearance` up to `height`. That span is the band whose geometry blocks: build-scene's occupancy, export-usd's
    collider band check and the replay's agent all use it. build-scene builds a run's maps for it and records it in
    semantic_map.json; every later stage takes it from there."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    radius: Annotated[float, Option("--agent-radius")] = Field(
        default=0.20, gt=0, description="Agent body's radius, m; the navigable map is inflated by it.")
    clearance: Annotated[float, Option("--band-min")] = Field(default=0.05, ge=0, description=(
        "Agent body's bottom above the floor, m: the lowest blocking height (a rug or a threshold below it is "
        "driven over)."))
    height: Annotated[float, Option("--band-max")] = Field(
        default=1.2, gt=0, description="Agent body's top above the floor, m: the highest blocking height.")

    @property
    def band(self) -> tuple[float, float]:
        """(bottom, top) of the blocking band above the floor, m: the body's span."""
        return self.clearance, self.height

    @field_validator("height")
    @classmethod
    def _above_clearance(cls, height: float, info: ValidationInfo) -> float:
        clearance = info.data.get("clearance")
        if clearance is not None and height <= clearance:
            raise ValueError(f"{height} must be above the band's bottom, clearance ({clearance})")
        return height


class CameraConfig(BaseModel):
    """The agent's camera: what each stage that renders views sees through (metres, degrees)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    height: Annotated[float, Option("--camera-height")] = Field(
        default=1.2, gt=0, description="Camera above the floor, m.")
    hfov_deg: Annotated[float, Option("--hfov")] = Field(
        default=90.0, gt=0, lt=180, description="Horizontal field of view, degrees.")


class ReplayConfig(BaseModel):
    """The replay's physics step and the path-following controller's limits."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    timestep: float = Field(default=0.05, gt=0, le=0.2, description="Physics and control step, s.")
    max_speed: float = Field(default=0.8, gt=0, description="Forward speed limit, m/s.")
    max_turn_rate: float = Field(default=1.5, gt=0, description="Turn-rate limit, rad/s.")
    turn_in_place: float = Field(default=0.1, gt=0, lt=math.pi / 2,
                                 description="Heading error above which the agent turns without driving, rad.")
    waypoint_tolerance: float = Field(default=0.02, gt=0, description="A waypoint counts as reached this close, m.")
    yaw_tolerance: float = Field(default=1e-3, gt=0, description="A turn-in-place waypoint's yaw is reached this close, rad.")
    time_factor: float = Field(default=1.5, ge=1, description="Time limit = time_factor x ideal time + time_slack.")
    time_slack: float = Field(default=3.0, ge=0, description="Seconds added to the time limit.")
    stall_time: float = Field(default=2.0, gt=0,
                              description="The replay stops when the agent came no nearer its waypoint for this long, s.")


class ActionConfig(BaseModel):
    """What one action does (defaults: VLN-CE's 0.25 m and 15 degrees)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    control_interval: float = Field(default=0.5, gt=0, le=5, description="Seconds one action lasts.")
    forward_step: float = Field(default=0.25, gt=0, description="MOVE_FORWARD distance, m.")
    turn_deg: float = Field(default=15.0, gt=0, le=180, description="TURN_LEFT / TURN_RIGHT angle, degrees.")


def beyond_limits(actions: ActionConfig, replay: ReplayConfig) -> str | None:
    """Why the discrete actions ask for more than the replay's drive holds (the speed and turn rate it can stop
    against a wall without tunnelling), naming the fields; None when they do not. Settings that hold both
    (EnvConfig) refuse such a pair."""
    speed = actions.forward_step / actions.control_interval
    if speed > replay.max_speed + 1e-12:
        return (f"actions.forward_step / actions.control_interval ({actions.forward_step:g} m / "
                f"{actions.control_interval:g} s = {speed:g} m/s) exceeds replay.max_speed ({replay.max_speed:g} m/s)")
    rate = math.radians(actions.turn_deg) / actions.control_interval
    if rate > replay.max_turn_rate + 1e-12:
        return (f"actions.turn_deg / actions.control_interval ({actions.turn_deg:g} deg / "
                f"{actions.control_interval:g} s = {rate:.4g} rad/s) exceeds replay.max_turn_rate "
                f"({replay.max_turn_rate:g} rad/s)")
    return None


@dataclass(frozen=True)
class MetricConfig:
    """Constants of the metrics; defaults are the paper's where it gives one, else docs/metrics.md's."""

    ndtw_threshold: float = 3.0  # d_th, m (habitat / VLN-CE)
    resample_spacing: float = 0.25  # reference resampling for nDTW and CSR, m
    corridor_radius: float = 1.0  # CSR r_tol, m (the paper gives none)


@dataclass(frozen=True)
class TaskMetricConfig:
    """Constants of the other tasks' metrics (docs/tasks/*.md); apart from MetricConfig so that a VLN run's results
    stay as they were."""

    viewpoint_tolerance: float = 0.1  # ObjectNav: success within this of a goal viewpoint on foot, m (habitat's 0.1)
    coverage_success: float = 0.1  # no-goal: success needs at least this coverage (and no collision); calibrated
    # on the demo (docs/tasks/nogoal.md): SAGE's 80 s sweep at most 0.40 of it, the explorer 0.13, a random walk 0.03
