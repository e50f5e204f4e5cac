"""rollout's settings (defaults here, nowhere else): the policy, which episodes, the closed-loop environment
(observation profile, actions, motion, renderer) and the policy server's protocol."""

from __future__ import annotations

from collections.abc import Callable
from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator

from sagebench.errors import ConfigError
from sagebench.settings.option import EXPAND, Option
from sagebench.settings.shared import (
    RENDERER, SPLITS, ActionConfig, CameraConfig, RendererChoice, ReplayConfig, Task, TokenizerSetting, VocabSetting,
    beyond_limits,
)

ProfileName = Literal["custom", "vlnce", "sage", "full"]
PROFILES: tuple[str, ...] = ("custom", "vlnce", "sage", "full")
PrivilegedKey = Literal["pose", "gps_compass", "instance"]
PRIVILEGED: tuple[str, ...] = ("pose", "gps_compass", "instance")
CameraKey = Literal["rgb", "depth"]  # the images a custom profile may name (instance is privileged)
Encoding = Literal["raw", "png", "json"]  # how images go to a policy server (navsim/protocol.py)


class ProfileError(ValueError):
    """A profile does not allow what was asked; `field` names the setting (profile, width, observations)."""

    def __init__(self, message: str, field: str):
        super().__init__(message)
        self.field = field


def check_profile(profile: str, *, width: int | None = None, height: int | None = None,
                  observations: tuple[str, ...] | None = None) -> None:
    """A ProfileError saying why `profile` does not allow the sizes or images asked for (navsim/profiles.py)."""
    if observations is not None and profile != "custom":
        raise ProfileError(f"the {profile} profile sets the images itself; observations are for the custom profile",
                           "observations")
    if "instance" in (observations or ()):
        raise ProfileError("instance ids are privileged: ask for them with --privileged instance", "observations")
    if profile == "vlnce" and (width is not None or height is not None):
        raise ProfileError("the vlnce profile's sizes are VLN-CE's (rgb 224x224, depth 256x256)", "width")
    if profile not in PROFILES:
        raise ProfileError(f"{profile!r} is not a profile (one of {', '.join(PROFILES)})", "profile")


def names(allowed: tuple[str, ...], option: str) -> Callable[[str], tuple[str, ...]]:
    """The parser of an option listing names: 'rgb,depth' -> ('rgb', 'depth'); 'none' -> (); a name not in
    `allowed` is a ConfigError naming `option`."""

    def parse(text: str) -> tuple[str, ...]:
        found = () if text.strip() == "none" else tuple(p.strip() for p in text.split(",") if p.strip())
        bad = [n for n in found if n not in allowed]
        if bad == ["instance"] and option == "--obs":
            raise ConfigError("instance ids are privileged: ask for them with --privileged instance", field=option)
        if bad or not text.strip():
            raise ConfigError(f"{(bad[0] if bad else text)!r} is not one of {', '.join(allowed)} (or none)",
                              field=option)
        return found

    return parse


class MotionConfig(BaseModel):
    """Collision recovery (the interval itself is the action's; navsim/motion.py)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    recovery_depth: float = Field(default=0.01, ge=0,
                                  description="An end pose penetrating deeper than this is recovered, m "
                                              "(validate's penetration tolerance).")


class EnvConfig(BaseModel):
    """The closed-loop environment's settings (navsim/simulator.py, the gym env)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    profile: Annotated[ProfileName, Option("--profile")] = Field(
        default="custom", description="Observations: custom (--obs at --width x --height), vlnce, sage or full "
                                      "(privileged included); navsim/profiles.py.")
    width: Annotated[int | None, Option("--width")] = Field(
        default=None, ge=1, le=4096, description="Image width, px (default: the profile's).")
    height: Annotated[int | None, Option("--height")] = Field(
        default=None, ge=1, le=4096, description="Image height, px (default: the profile's).")
    camera: CameraConfig = CameraConfig()
    observations: Annotated[tuple[str, ...] | None, Option("--obs", parse=names(("rgb", "depth"), "--obs"))] = Field(
        default=None, description="custom profile: images to render, rgb and/or depth (default both), or none (the "
                                  "instruction only).")
    privileged: Annotated[tuple[PrivilegedKey, ...], Option("--privileged", parse=names(PRIVILEGED, "--privileged"))
                          ] = Field(default=(), description="Privileged observations to add, comma-separated: pose, "
                                                            "gps_compass, instance (full has them all).")
    task: Annotated[Task, Option("--task")] = Field(
        default="vln", description="Which task's episodes to run, each agent told of its goal as that task says: vln "
                                   "(the instruction), nogoal (the exploration instruction), pointnav (pointgoal), "
                                   "objectnav (objectgoal) or imagenav (imagegoal); docs/tasks.md.")
    tokenizer: TokenizerSetting
    vocab: VocabSetting
    success_distance: float | None = Field(
        default=None, gt=0, description="Success radius instead of each episode's goal_radius, m.")
    max_steps: Annotated[int, Option("--max-steps")] = Field(
        default=500, ge=1, description="Actions per episode before it is cut off.")
    action_space: Annotated[Literal["discrete", "continuous"], Option("--action-space")] = Field(
        default="discrete", description="discrete (STOP, MOVE_FORWARD, TURN_LEFT, TURN_RIGHT) or continuous (v m/s, "
                                        "omega rad/s, stop).")
    actions: ActionConfig = ActionConfig()
    motion: MotionConfig = MotionConfig()
    replay: ReplayConfig = ReplayConfig()
    renderer: Annotated[RendererChoice, Option("--renderer")] = Field(default="auto", description=RENDERER)

    @model_validator(mode="after")
    def _checked(self) -> EnvConfig:
        check_profile(self.profile, width=self.width, height=self.height, observations=self.observations)
        problem = beyond_limits(self.actions, self.replay)
        if problem:
            raise ValueError(problem)
        return self


class RolloutConfig(BaseModel):
    """Settings of rollout."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    policy: Annotated[str, Option("--policy")] = Field(
        default="oracle", description="A policy server's http(s):// URL, oracle, straight, random, "
                                      "vlnce:MODULE:NAME (a VLN-CE agent class or object, run in-process), or a "
                                      "SAGE-Bench model server: sage+http://HOST:PORT[/nogoal_step] or "
                                      "sage+socket://HOST:PORT (docs/sage_models.md).")
    split: Annotated[str | None, Option("--split", values=SPLITS)] = Field(
        default=None, description="Only this split's episodes: train, val_seen, val_unseen, test, trajectory_unseen or instruction_unseen.")
    episode_ids: Annotated[tuple[str, ...], Option("--episode-id")] = Field(
        default=(), description="Only these episodes (repeat --episode-id for more).")
    episodes: Annotated[int | None, Option("--episodes")] = Field(
        default=None, ge=1, description="Run a seeded sample of N of those episodes (default: all).")
    seed: Annotated[int, Option("--seed")] = Field(
        default=0, description="Seed of the episode sample and of the random policy.")
    preset: Annotated[Literal["vlnce"] | None, Option("--preset")] = Field(
        default=None, description="Another benchmark's settings: vlnce (success distance 3 m, VLN-CE's camera, "
                                  "actions and observations; the body stays the one the run's maps were built for).")
    workers: Annotated[int, Option("--workers")] = Field(
        default=2, ge=1, description="Threads stepping MuJoCo and calling the policy server.")
    threads: Annotated[int | None, Option("--threads")] = Field(
        default=None, ge=1, description="Cores the renderer's threads use, which wait passively when idle (default: "
                                        "every core this process may run on).")
    batch: Annotated[int, Option("--batch")] = Field(
        default=8, ge=1, description="Episodes stepped together (results do not depend on it).")
    policy_timeout: Annotated[float, Option("--policy-timeout")] = Field(
        default=60.0, gt=0, description="Deadline of one policy request, s: connecting, sending and the whole reply.")
    policy_retries: Annotated[int, Option("--policy-retries")] = Field(
        default=3, ge=0, description="Retries of a policy request after a connection error, with backoff, within its "
                                     "deadline.")
    policy_encoding: Annotated[Encoding, Option("--policy-encoding")] = Field(
        default="raw", description="How images go to a policy server: raw, png (RGB as PNG) or json (base64 PNG and "
                                   ".npy, as before).")
    max_policy_failures: Annotated[int, Option("--max-policy-failures")] = Field(
        default=10, ge=0, description="Episodes the policy may fail (a request that failed) before the rollout stops.")
    sheet_episodes: int = Field(default=4, ge=0, description="Episodes shown on the contact sheet.")
    env: Annotated[EnvConfig, EXPAND] = EnvConfig()

    def decisive(self) -> dict:
        """The settings that decide the predictions (the record keeps them for --resume)."""
        out = self.model_dump(mode="json", include={"policy", "seed", "preset", "env"})
        if out["env"]["task"] == "vln":  # a VLN rollout's record reads as it did before tasks existed
            del out["env"]["task"]
        return out
