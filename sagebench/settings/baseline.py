"""baseline's settings (defaults here, nowhere else): `rollout --policy AGENT --obs none` with the baselines'
options."""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field

from sagebench.settings.option import Option
from sagebench.settings.rollout import EnvConfig, RolloutConfig
from sagebench.settings.shared import Task


class BaselineConfig(BaseModel):
    """Settings of baseline."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    agent_name: Annotated[Literal["oracle", "straight", "random", "stationary", "explorer"],
                          Option("--agent", required=True)] = Field(
        default="oracle", description="Which baseline: oracle, straight, random, stationary (stops at once) or "
                                      "explorer (no-goal: sweeps the nearest unswept floor of the map).")
    task: Annotated[Task, Option("--task")] = Field(
        default="vln", description="Which task's episodes to run: vln, nogoal, objectnav, pointnav or imagenav.")
    seed: Annotated[int, Option("--seed")] = Field(default=0, ge=0, description="Seed of the random agent's walks.")
    max_actions: Annotated[int, Option("--max-actions")] = Field(
        default=500, ge=1, description="Actions per episode before it ends unstopped.")
    workers: Annotated[int, Option("--workers")] = Field(
        default=2, ge=1, description="Threads stepping the MuJoCo agents.")

    def rollout(self) -> RolloutConfig:
        """The rollout these settings name."""
        return RolloutConfig(policy=self.agent_name, seed=self.seed, workers=self.workers, sheet_episodes=0,
                             env=EnvConfig(observations=(), privileged=("pose",), max_steps=self.max_actions,
                                           task=self.task))
