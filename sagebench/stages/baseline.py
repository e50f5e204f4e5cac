"""`baseline`: run a baseline agent (oracle, straight, random) on a run's episodes and write its predictions.

Reads RUN/episodes/<id>/part-*.parquet and RUN/scenes/<id>/scene.json + scene.xml (export-usd). Writes one
predictions JSON Lines file (episodes in scene then shard order), with the collision intensity each action met.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Literal

from pydantic import BaseModel, ConfigDict, Field

from sagebench import ui
from sagebench.agents.driver import drive
from sagebench.agents.policies import PolicyConfig, make_policy
from sagebench.config import AgentConfig, from_options
from sagebench.episodes.load import load_episodes
from sagebench.evaluation.intensity import STEP_REPLAY
from sagebench.evaluation.predictions import Prediction, write_predictions
from sagebench.replay.physics import ReplayConfig
from sagebench.replay.scene_model import open_replay_model


class BaselineConfig(BaseModel):
    """Settings of baseline (defaults here, nowhere else); the CLI maps its options onto these fields."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    agent_name: Literal["oracle", "straight", "random"] = Field(default="oracle", description="Which baseline.")
    seed: int = Field(default=0, ge=0, description="Seed of the random agent's walks.")
    max_actions: int = Field(default=500, ge=1, description="Actions per episode before it ends unstopped.")
    policy: PolicyConfig = PolicyConfig()
    agent: AgentConfig = AgentConfig()
    replay: ReplayConfig = STEP_REPLAY
    workers: int = Field(default=2, ge=1, description="Threads stepping the MuJoCo agents.")


# baseline's options and the BaselineConfig fields they set (their defaults and error names come from here)
OPTIONS = {"--agent": "agent_name", "--max-actions": "max_actions", "--workers": "workers", "--seed": "seed"}


def make_config(**fields: object) -> BaselineConfig:
    """A BaselineConfig from the options given (None = keep the default); a bad value is a ConfigError."""
    return from_options(BaselineConfig, fields, OPTIONS)


@dataclass(frozen=True)
class BaselineResult:
    agent_name: str
    out: Path
    episodes: int
    stopped: int
    actions: int

    def summary(self) -> str:
        return (f"baseline {self.agent_name}: {self.episodes} episodes ({self.stopped} stopped by the agent, "
                f"{self.actions} actions) -> {self.out}")


def run_baseline(run_dir: Path, out: Path, config: BaselineConfig = BaselineConfig(), *,
                 scene_id: str | None = None) -> BaselineResult:
    """Drive the agent through every episode of the run (or `scene_id`) and write `out` whole."""
    run_dir = Path(run_dir)
    episodes = load_episodes(run_dir, scene_id)
    scenes = list(dict.fromkeys(e.scene_id for e in episodes))
    models = {sid: open_replay_model(run_dir, sid, agent=config.agent, replay=config.replay) for sid in scenes}
    predictions: list[Prediction] = []
    for sid in ui.track(scenes, f"baseline {config.agent_name}"):
        mine = [e for e in episodes if e.scene_id == sid]
        policy = make_policy(config.agent_name, mine, config.policy, seed=config.seed)
        predictions += drive(models[sid], mine, policy, max_actions=config.max_actions, threads=config.workers)
    write_predictions(Path(out), predictions)
    return BaselineResult(agent_name=config.agent_name, out=Path(out), episodes=len(predictions),
                          stopped=sum(p.stopped for p in predictions),
                          actions=sum(len(p.poses) - 1 for p in predictions))

