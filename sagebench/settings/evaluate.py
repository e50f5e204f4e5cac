"""evaluate's settings (defaults here, nowhere else): the metrics' constants, the step replay that derives
collision intensity, and what is scored."""

from __future__ import annotations

from typing import Annotated

from pydantic import BaseModel, ConfigDict, Field

from sagebench.settings.option import Option
from sagebench.settings.shared import MetricConfig, ReplayConfig

# Replay settings for single agent steps: a step ends within 5 mm of its target (not 2 cm: the deadbeat drive
# lands on it exactly, so short steps do not fall short), a blocked step gives up after 0.5 s without progress
# (not 2 s), and the time limit's slack is 1 s, since a step is short.
STEP_REPLAY = ReplayConfig(stall_time=0.5, time_slack=1.0, waypoint_tolerance=0.005)


class EvaluateConfig(BaseModel):
    """Settings of evaluate."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    metrics: MetricConfig = MetricConfig()
    replay: ReplayConfig = STEP_REPLAY
    allow_missing: Annotated[bool, Option("--allow-missing")] = Field(
        default=False, description="Score episodes without a prediction as failures instead of stopping.")
    all_episodes: Annotated[bool, Option("--all-episodes")] = Field(
        default=False, description="With a rollout's predictions: score every episode of the run (or --scene/--split), "
                                   "not only those the rollout was asked to run.")
    start_tolerance: Annotated[float, Option("--start-tolerance")] = Field(
        default=0.10, gt=0, description="Largest distance of the first pose from the episode's start (XY), m.")
    workers: Annotated[int, Option("--workers")] = Field(
        default=2, ge=1, description="Threads replaying poses for collision intensity.")
