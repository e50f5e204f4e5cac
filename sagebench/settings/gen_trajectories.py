"""gen-trajectories' settings (defaults here, nowhere else): sampling, instructions, the chat model, splits, the
tasks and what is written; run.toml's [gen_trajectories] table."""

from __future__ import annotations

import urllib.parse
from pathlib import Path
from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field, SerializerFunctionWrapHandler, field_validator, model_serializer, model_validator

from sagebench.settings.option import EXPAND, Option
from sagebench.settings.rollout import names
from sagebench.settings.shared import TASKS, Task

PairKind = Literal["object-object", "object-room", "room-object", "room-room"]
HIGH_LEVEL_TYPES = ("Add_Object", "Scenario_Driven", "Relative_Relationship", "Attribute_Based", "Area_Based")


class SamplingConfig(BaseModel):
    """How many trajectories per scene, between what, and how long (metres): what the A* sampler reads."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    per_scene: Annotated[int, Option("--per-scene")] = Field(
        default=200, ge=1, description="Distinct trajectories per scene.")
    seed: Annotated[int, Option("--seed")] = Field(
        default=0, ge=0, description="Seed of every random choice: sampling and wording.")
    min_geodesic_m: Annotated[float, Option("--min-geodesic")] = Field(
        default=2.0, ge=0, description="Shortest accepted path, m.")
    max_geodesic_m: Annotated[float, Option("--max-geodesic")] = Field(
        default=20.0, gt=0, description="Longest accepted path, m.")
    approach_max_m: float = Field(default=1.0, gt=0, description="Farthest a stand point may be from a footprint, m.")
    approach_tolerance_m: float = Field(
        default=0.1, ge=0, description="Stand points within this of the nearest one count as nearest, m.")
    pair_mix: dict[PairKind, float] = Field(
        default={"object-object": 0.6, "object-room": 0.15, "room-object": 0.15, "room-room": 0.1},
        description="Relative share of each (start kind)-(goal kind) pair.")

    @model_validator(mode="after")
    def _range(self) -> SamplingConfig:
        if self.min_geodesic_m >= self.max_geodesic_m:
            raise ValueError(f"min_geodesic_m ({self.min_geodesic_m}) must be below max_geodesic_m ({self.max_geodesic_m})")
        if not any(v > 0 for v in self.pair_mix.values()) or any(v < 0 for v in self.pair_mix.values()):
            raise ValueError("pair_mix needs non-negative shares, at least one positive")
        return self


class SplitConfig(BaseModel):
    """Split fractions and their seed (episodes/splits.py)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    val_unseen: float = Field(default=0.1, ge=0, le=1, description="Share of scenes held out for val_unseen.")
    test: float = Field(default=0.1, ge=0, le=1, description="Share of scenes held out for test.")
    val_seen: float = Field(default=0.1, ge=0, le=1,
                            description="Share of the seen scenes' trajectories for val_seen (the rest: train).")
    seed: int = Field(default=0, ge=0, description="Seed of the split hashes.")
    trajectory_unseen: float = Field(default=0.0, ge=0, le=1, description=(
        "Share of the seen scenes' trajectories held out for trajectory_unseen (SAGE-Bench's Trajectory-Unseen)."))
    instruction_unseen: float = Field(default=0.0, ge=0, le=1, description=(
        "Share of the train trajectories whose high-level instruction is held out for instruction_unseen "
        "(SAGE-Bench's Instruction-Unseen; the trajectory's other rows stay in train)."))

    @model_validator(mode="after")
    def _fractions(self) -> SplitConfig:
        if self.val_unseen + self.test > 1:
            raise ValueError(f"val_unseen + test is {self.val_unseen + self.test:g} of the scenes (at most 1)")
        if self.val_seen + self.trajectory_unseen > 1:
            raise ValueError(f"val_seen + trajectory_unseen is {self.val_seen + self.trajectory_unseen:g} of the "
                             "trajectories (at most 1)")
        return self

    @model_serializer(mode="wrap")
    def _as_before(self, handler: SerializerFunctionWrapHandler) -> dict:
        """The held-out shares dump only when set, so a config without them keeps its stamps' keys."""
        data = handler(self)
        for name in ("trajectory_unseen", "instruction_unseen"):
            if not data.get(name):
                data.pop(name, None)
        return data


class LLMConfig(BaseModel):
    """The chat model and how to call it (instructions/llm_client.py)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    base_url: Annotated[str | None, Option("--llm-base-url")] = Field(
        default=None, description="OpenAI-compatible API root for llm instructions, e.g. http://localhost:8000/v1.")
    model: Annotated[str | None, Option("--llm-model")] = Field(
        default=None, description="Chat model name sent with each LLM request.")
    cache_dir: Annotated[Path | None, Option("--llm-cache-dir")] = Field(
        default=None,
        description="Answer cache, keyed by sha256 of (model, prompt) (default: the user cache directory).")
    concurrency: Annotated[int | None, Option("--llm-concurrency")] = Field(default=None, ge=1, le=64, description=(
        "LLM requests in flight at once (default: the slots the server reports, as a llama.cpp server does at "
        "/props, else 1 for a server on this machine or the local network, else 4)."))
    timeout_s: Annotated[float, Option("--llm-timeout")] = Field(
        default=60.0, gt=0, description="Deadline of one whole LLM request attempt, from sending it to its last byte, s.")
    max_attempts: Annotated[int, Option("--llm-attempts")] = Field(
        default=3, ge=1, description="HTTP attempts per LLM request (429, 5xx and timeouts are retried).")
    backoff_s: float = Field(default=1.0, ge=0, description="First retry delay, s; doubles per attempt.")
    breaker_failures: int = Field(default=6, ge=1,
                                  description="Consecutive failed attempts (all threads) after which no request is sent.")
    answer_attempts: int = Field(default=2, ge=1, description="Answers asked for before the template is kept.")
    temperature: Annotated[float, Option("--llm-temperature")] = Field(
        default=0.0, ge=0, description="Sampling temperature sent with each LLM request.")
    max_tokens: Annotated[int, Option("--llm-max-tokens")] = Field(
        default=200, ge=16, description="Longest LLM answer the server may generate, tokens.")
    response_format: Annotated[Literal["auto", "json_schema", "json_object", "none"],
                               Option("--llm-response-format")] = Field(
        default="auto", description=("How to ask the LLM for JSON: auto (json_schema, else json_object, else none, "
                                     "decided by the first request), json_schema, json_object or none."))
    prompt_tokens: int = Field(default=3000, ge=500,
                               description="Prompt budget, tokens (estimated); a longer scene map is shortened.")
    min_share: Annotated[float, Option("--llm-min-share")] = Field(
        default=0.5, ge=0, le=1,
        description="Exit 1 (writing nothing) when a scene gets a smaller share of high-level rows from the LLM; with "
                    "no LLM row it always does.")
    refresh: Annotated[bool, Option("--llm-refresh")] = Field(
        default=False, description="Ask the LLM again even for prompts the answer cache holds.")

    @field_validator("base_url")
    @classmethod
    def _http_url(cls, url: str | None) -> str | None:
        parsed = urllib.parse.urlparse(url or "http://x")
        if parsed.scheme not in ("http", "https") or not parsed.hostname:
            raise ValueError(f"must be an http(s) URL such as http://localhost:8000/v1, got {url!r}")
        return url


def _comma_list(text: str) -> tuple[str, ...]:
    """'chair, bed' -> ('chair', 'bed')."""
    return tuple(p.strip() for p in text.split(",") if p.strip())


class TaskConfig(BaseModel):
    """The episodes of the tasks other than vln (episodes/task_rows.py): how many, their budgets and success radii."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    episodes: Annotated[int, Option("--task-episodes")] = Field(
        default=20, ge=1, description="Episodes per scene of each task other than vln.")
    nogoal_budget_s: Annotated[float, Option("--nogoal-budget")] = Field(
        default=80.0, gt=0, description="Time budget of a nogoal episode, s (SAGE-Bench's 80 s).")
    nogoal_budget_steps: int = Field(
        default=160, ge=1, description="Step budget of a nogoal episode: 80 s of 0.5 s actions.")
    objectnav_categories: Annotated[tuple[str, ...] | None, Option("--objectnav-categories", parse=_comma_list)] = Field(
        default=None, description="ObjectNav goal categories, comma-separated (default: every category with an "
                                  "instance the agent can stand by); one with no such instance in a scene is an error.")
    objectnav_success_m: float = Field(
        default=1.0, gt=0, description="ObjectNav success distance from any instance's footprint, m.")
    pointnav_success_m: float = Field(default=0.2, gt=0, description="PointNav success distance, m (habitat's SUCCESS_DISTANCE).")
    imagenav_success_m: float = Field(default=1.0, gt=0, description="ImageNav success distance, m.")


class GenTrajectoriesConfig(SamplingConfig):
    """Settings of gen-trajectories: sampling plus what is written."""

    shard_mb: Annotated[float, Option("--shard-mb")] = Field(
        default=128.0, gt=0, description="Largest Parquet shard, MB (one split per shard).")
    instructions: Annotated[Literal["template", "llm", "none"], Option("--instructions")] = Field(
        default="template",
        description="template: two low-level rows (Base_Action, Single_Goal) and one high-level row per trajectory; "
                    "llm: the high-level row from a chat model (grounded, else the template), and each nogoal "
                    "episode's instruction its phrasing of SAGE-Bench's; none: one bare row per trajectory.")
    goal_radius_m: Annotated[float, Option("--goal-radius")] = Field(
        default=1.0, gt=0,
        description="Success radius written with each episode, m: the stand point is ~0.2-0.3 m from the target, so "
                    "1 m means next to it.")
    high_level_mix: dict[Literal[HIGH_LEVEL_TYPES], float] = Field(  # type: ignore[valid-type]
        default={t: 1.0 for t in HIGH_LEVEL_TYPES},
        description="Relative share of each high-level type (a type that cannot describe a goal is skipped).")
    llm: Annotated[LLMConfig, EXPAND] = Field(default=LLMConfig(), description="Chat model for --instructions llm.")
    preview_paths: int = Field(default=40, ge=0, description="Paths drawn in paths.png.")
    splits: SplitConfig = Field(default=SplitConfig(), description="Split fractions and seed (episodes/splits.py).")
    tasks: Annotated[tuple[Task, ...], Option("--tasks", parse=names(TASKS, "--tasks"))] = Field(
        default=("vln",), description="Tasks to write episodes for, comma-separated: vln, nogoal, objectnav, pointnav, "
                                      "imagenav (docs/tasks.md).")
    task: Annotated[TaskConfig, EXPAND] = Field(default=TaskConfig(), description="The other tasks' episodes.")

    @model_validator(mode="after")
    def _instruction_settings(self) -> GenTrajectoriesConfig:
        if any(v < 0 for v in self.high_level_mix.values()) or not any(v > 0 for v in self.high_level_mix.values()):
            raise ValueError("high_level_mix needs non-negative shares, at least one positive")
        if self.instructions == "llm" and not (self.llm.base_url and self.llm.model):
            raise ValueError("--instructions llm needs --llm-base-url and --llm-model")
        if self.instructions != "llm" and self.llm != LLMConfig():
            raise ValueError("--llm-* options (the llm table) are used only with --instructions llm")
        if not self.tasks or len(set(self.tasks)) != len(self.tasks):
            raise ValueError("--tasks needs at least one task, each named once")
        if self.tasks == ("vln",) and self.task != TaskConfig():
            raise ValueError("the task table's options are used only with --tasks other than vln")
        return self

    @model_serializer(mode="wrap")
    def _vln_as_before(self, handler: SerializerFunctionWrapHandler) -> dict:
        """A vln-only config dumps as before tasks existed, so its stamps' keys and the manifest stay the same."""
        data = handler(self)
        if self.tasks == ("vln",):
            data.pop("tasks", None)
            data.pop("task", None)
        return data
