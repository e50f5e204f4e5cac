"""`rollout`: run a policy closed-loop in the simulator over a run's episodes and write its predictions.

Reads RUN/episodes/<id>/part-*.parquet, RUN/scenes/<id>/scene.json, topdown.npz, gaussians.ply (when images are
rendered) and scene.xml + colliders (export-usd). Writes OUT (predictions JSON Lines, episodes in run order,
c(t) measured by the simulator and marked so) and, when RGB is rendered, OUT's stem + _contact_sheet.png
(start, middle and end views of the first few episodes).

`baseline` is this stage's alias for the built-in policies with no images (`rollout --policy AGENT --obs none`),
kept for its options: one implementation of the baselines, their c(t) the simulator's measured one.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import cv2
import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from sagebench import ui
from sagebench.config import from_options
from sagebench.errors import ConfigError
from sagebench.evaluation.predictions import write_predictions
from sagebench.fileio import write_bytes
from sagebench.navsim.http_policy import HttpPolicy
from sagebench.navsim.observe import IMAGE_KEYS
from sagebench.navsim.policies import BUILT_IN, built_in
from sagebench.navsim.rollout import contact_sheet, rollout
from sagebench.navsim.simulator import EnvConfig, Simulator
from sagebench.threads import share_cores


class RolloutConfig(BaseModel):
    """Settings of rollout (defaults here, nowhere else); the CLI maps its options onto these fields."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    policy: str = Field(default="oracle", description="An http(s):// URL of a policy server, or oracle, straight, random.")
    episodes: int | None = Field(default=None, ge=1, description="Run a seeded sample of this many episodes.")
    seed: int = Field(default=0, description="Seed of the episode sample and of the random policy.")
    workers: int = Field(default=2, ge=1, description="Threads stepping MuJoCo and calling the policy server.")
    threads: int | None = Field(default=None, ge=1, description="Cores the renderer's threads use (default: every "
                                                                "core this process may run on).")
    batch: int = Field(default=8, ge=1, description="Episodes stepped together.")
    policy_timeout: float = Field(default=60.0, gt=0, description="Seconds to wait for a policy server's reply.")
    sheet_episodes: int = Field(default=4, ge=0, description="Episodes shown on the contact sheet.")
    env: EnvConfig = EnvConfig(observations=("rgb", "depth"))


# rollout's options and the RolloutConfig fields they set (their defaults and error names come from here)
OPTIONS = {"--policy": "policy", "--episodes": "episodes", "--seed": "seed", "--workers": "workers",
           "--threads": "threads",
           "--width": "env.width", "--height": "env.height", "--max-steps": "env.max_steps",
           "--obs": "env.observations"}


def parse_obs(text: str) -> tuple[str, ...]:
    """'rgb,depth' -> ('rgb', 'depth'); 'none' -> (); an unknown name is a ConfigError."""
    names = () if text.strip() == "none" else tuple(p.strip() for p in text.split(",") if p.strip())
    bad = [n for n in names if n not in IMAGE_KEYS]
    if bad or not text.strip():
        raise ConfigError(f"{(bad[0] if bad else text)!r} is not one of {', '.join(IMAGE_KEYS)} (or none)", field="--obs")
    return names


def make_config(*, width: int | None = None, height: int | None = None, max_steps: int | None = None,
                obs: str | None = None, **fields: object) -> RolloutConfig:
    """A RolloutConfig from the options given (None = default); a bad value is a ConfigError naming the option."""
    env = {"width": width, "height": height, "max_steps": max_steps,
           "observations": parse_obs(obs) if obs is not None else None}
    default_obs = RolloutConfig().env.observations
    config = from_options(RolloutConfig, {**fields, "env": {"observations": default_obs, **env}}, OPTIONS)
    p = config.policy
    if p not in BUILT_IN and not p.startswith(("http://", "https://")):
        raise ConfigError(f"{p!r} is neither an http(s):// URL nor one of {', '.join(BUILT_IN)}", field="--policy")
    return config


@dataclass(frozen=True)
class RolloutSummary:
    policy: str
    out: Path
    sheet: Path | None
    episodes: int
    stopped: int
    steps: int
    seconds: float

    def summary(self) -> str:
        sheet = f" and {self.sheet}" if self.sheet else ""
        return (f"rollout {self.policy}: {self.episodes} episodes ({self.stopped} stopped by the policy), "
                f"{self.steps} steps, {self.steps / max(self.seconds, 1e-9):.1f} steps/s -> {self.out}{sheet}")


def sheet_path(out: Path) -> Path:
    return Path(out).with_name(Path(out).stem + "_contact_sheet.png")


def run_rollout(run_dir: Path, out: Path, config: RolloutConfig = RolloutConfig(), *,
                scene_id: str | None = None) -> RolloutSummary:
    """Roll the policy out over the run's episodes (or a sample) and write `out` (and the contact sheet) whole."""
    share_cores(config.threads)
    sim = Simulator(run_dir, config.env, scene_id=scene_id, threads=config.workers)
    ids = list(sim.order)
    if config.episodes is not None and config.episodes < len(ids):
        pick = np.sort(np.random.default_rng(config.seed).permutation(len(ids))[: config.episodes])
        ids = [ids[i] for i in pick]
    if config.policy in BUILT_IN:
        policy = built_in(config.policy, seed=config.seed, actions=config.env.actions)
    else:
        policy = HttpPolicy(config.policy, action_space=config.env.action_space, timeout=config.policy_timeout,
                            workers=config.workers)
    start = time.perf_counter()
    with ui.progress(len(ids), f"rollout {config.policy}") as update:
        def on_step(done: int, steps: int) -> None:
            update(done, f"{steps / max(time.perf_counter() - start, 1e-9):.1f} steps/s")

        result = rollout(sim, policy, ids, batch=config.batch, sheet=config.sheet_episodes, on_step=on_step)
    seconds = time.perf_counter() - start
    sheet = None
    if result.views:
        sheet = sheet_path(out)
        _, png = cv2.imencode(".png", contact_sheet(result.views)[:, :, ::-1])
        write_bytes(sheet, png.tobytes())
    write_predictions(Path(out), result.predictions)
    return RolloutSummary(policy=config.policy, out=Path(out), sheet=sheet, episodes=len(result.predictions),
                          stopped=sum(p.stopped for p in result.predictions), steps=result.steps, seconds=seconds)


class BaselineConfig(BaseModel):
    """Settings of baseline (defaults here, nowhere else); the CLI maps its options onto these fields."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    agent_name: Literal["oracle", "straight", "random"] = Field(default="oracle", description="Which baseline.")
    seed: int = Field(default=0, ge=0, description="Seed of the random agent's walks.")
    max_actions: int = Field(default=500, ge=1, description="Actions per episode before it ends unstopped.")
    workers: int = Field(default=2, ge=1, description="Threads stepping the MuJoCo agents.")

    def rollout(self) -> RolloutConfig:
        """The rollout these settings name."""
        return RolloutConfig(policy=self.agent_name, seed=self.seed, workers=self.workers, sheet_episodes=0,
                             env=EnvConfig(observations=(), max_steps=self.max_actions))


# baseline's options and the BaselineConfig fields they set (their defaults and error names come from here)
BASELINE_OPTIONS = {"--agent": "agent_name", "--max-actions": "max_actions", "--workers": "workers", "--seed": "seed"}


def make_baseline_config(**fields: object) -> BaselineConfig:
    """A BaselineConfig from the options given (None = keep the default); a bad value is a ConfigError."""
    return from_options(BaselineConfig, fields, BASELINE_OPTIONS)


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
    """Roll the agent out over every episode of the run (or `scene_id`) and write `out` whole."""
    done = run_rollout(Path(run_dir), Path(out), config.rollout(), scene_id=scene_id)
    return BaselineResult(agent_name=config.agent_name, out=done.out, episodes=done.episodes, stopped=done.stopped,
                          actions=done.steps)
