"""`rollout`: run a policy closed-loop in the simulator over a run's episodes and write its predictions.

Reads RUN/episodes/<id>/part-*.parquet, RUN/scenes/<id>/scene.json, topdown.npz, gaussians.ply (when images are
rendered) and scene.xml + colliders (export-usd). Writes OUT (predictions JSON Lines, episodes in run order,
c(t) measured by the simulator and marked so) and, when RGB is rendered, OUT's stem + _contact_sheet.png
(start, middle and end views of the first few episodes).

`baseline` is this stage's alias for the built-in policies with no images (`rollout --policy AGENT --obs none`),
kept for its options: one implementation of the baselines, their c(t) the simulator's measured one.
"""

from __future__ import annotations

import importlib
import re
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import cv2

from sagebench import ui
from sagebench.adapters.vlnce import PRESETS, VlnceAgents, body_note, preset_differences, preset_env
from sagebench.errors import ConfigError, DataError, Interrupted
from sagebench.evaluation.record import (
    Observed, RolloutRecord, is_record, is_rollout_predictions, read_record, record_path,
)
from sagebench.fileio import write_bytes
from sagebench.metrics.on_foot import NavigableMap
from sagebench.navsim.http_policy import HttpPolicy
from sagebench.navsim.policies import BUILT_IN, Policy, built_in
from sagebench.navsim.profiles import Sensors, env_sensors
from sagebench.navsim.resumable import run_into
from sagebench.navsim.rollout import contact_sheet, select_episodes
from sagebench.navsim.sage_policy import SCHEMES as SAGE_SCHEMES
from sagebench.navsim.sage_policy import SagePolicy, sage_server
from sagebench.navsim.simulator import Simulator
from sagebench.png_mark import is_marked, marked
from sagebench.run_folder import Output, claim_output_file
from sagebench.settings.baseline import BaselineConfig
from sagebench.settings.option import from_options, parsed
from sagebench.settings.rollout import EnvConfig, ProfileError, RolloutConfig, check_profile
from sagebench.threads import share_cores


AGENT_SPEC = re.compile(r"vlnce:(?P<module>[\w.]+):(?P<name>\w+)")  # a VLN-CE agent (class or object) to import
PolicyKind = Literal["built-in", "sage", "vlnce", "http"]

# options that decide the predictions: a resumed rollout takes them from its record
DECISIVE_OPTIONS = ("--split", "--episode-id", "--episodes", "--seed", "--preset", "--profile", "--width", "--height",
                    "--max-steps", "--obs", "--privileged", "--action-space", "--tokenizer", "--vocab")
PROFILE_FIELDS = {"profile": "--profile", "width": "--width", "observations": "--obs"}


def make_config(given: Mapping[str, object], *, resume: bool = False) -> RolloutConfig:
    """A RolloutConfig from the options given ({"--width": 320}; None = default) over --preset's settings; a bad
    value is a ConfigError naming the option. With `resume`, options that decide the predictions are refused (the
    record's are used)."""
    if resume:
        _refuse_on_resume(given, given.get("--policy"))
    given = parsed(RolloutConfig, given)
    if policy_kind(str(given.get("--policy") or "")) == "sage" and given.get("--preset") is None:
        # SAGE's models see SAGE's images and move freely, unless told otherwise (then refused below)
        given = {**given, "--profile": given.get("--profile") or "sage",
                 "--action-space": given.get("--action-space") or "continuous"}
    preset = given.get("--preset")
    if preset is not None and preset not in PRESETS:
        raise ConfigError(f"{preset!r} is not a preset (one of {', '.join(PRESETS)})", field="--preset")
    base = preset_env(preset) if preset is not None else {}
    profile, observations = (given[o] if given.get(o) is not None else base.get(k)
                             for k, o in (("profile", "--profile"), ("observations", "--obs")))
    try:
        check_profile(profile or "custom", width=given.get("--width"), height=given.get("--height"),
                      observations=observations)
    except ProfileError as err:
        raise ConfigError(str(err), field=PROFILE_FIELDS[err.field]) from None
    config = from_options(RolloutConfig, given, {"env": base})
    p, kind = config.policy, policy_kind(config.policy)
    if kind is None:
        raise ConfigError(f"{p!r} is neither an http(s):// URL, sage+http:// or sage+socket:// URL, "
                          f"vlnce:MODULE:NAME nor one of {', '.join(BUILT_IN)}", field="--policy")
    if kind == "sage":
        _check_sage(config)
    if kind == "built-in" and config.env.action_space != "discrete":
        raise ConfigError(f"the built-in policy {p} acts in the discrete action space", field="--action-space")
    if kind == "vlnce" and (config.env.profile, config.env.action_space) != ("vlnce", "discrete"):
        raise ConfigError("a VLN-CE agent needs the vlnce profile and discrete actions (--preset vlnce)",
                          field="--profile")
    if config.env.vocab is not None and not env_sensors(config.env).tokens:
        raise ConfigError(f"the {config.env.profile} profile has no instruction_tokens (vlnce and full have)",
                          field="--vocab")
    if kind == "built-in" and "pose" not in config.env.privileged:  # the baselines steer by the pose: say so
        config = from_options(RolloutConfig, {**given, "--privileged": (*config.env.privileged, "pose")}, {"env": base})
    return config


def policy_kind(policy: str) -> PolicyKind | None:
    """Which client runs `policy` (None: none can): the one place a --policy string is classified."""
    if policy in BUILT_IN:
        return "built-in"
    if policy.startswith(SAGE_SCHEMES):
        return "sage"
    if AGENT_SPEC.fullmatch(policy):
        return "vlnce"
    return "http" if policy.startswith(("http://", "https://")) else None


def _check_sage(config: RolloutConfig) -> None:
    """A ConfigError when a SAGE model server (navsim/sage_policy.py) cannot run as configured."""
    try:
        sage_server(config.policy)
    except ValueError as err:
        raise ConfigError(str(err), field="--policy") from None
    env = config.env
    if env.profile != "sage":
        raise ConfigError("a SAGE model server gets SAGE's observations: --profile sage", field="--profile")
    if env.action_space != "continuous":
        raise ConfigError("a SAGE model server's answers are velocities: --action-space continuous",
                          field="--action-space")
    if env.task not in ("vln", "nogoal"):
        raise ConfigError("SAGE's model protocol carries an instruction: --task vln or nogoal", field="--task")


def _refuse_on_resume(given: Mapping[str, object], policy: object) -> None:
    """A ConfigError for an option that decides the predictions, or a built-in policy, given with --resume."""
    clash = [opt for opt in DECISIVE_OPTIONS if given.get(opt) not in (None, ())]
    if clash:
        raise ConfigError("not with --resume: a resumed rollout keeps the settings it was started with",
                          field=clash[0])
    if policy_kind(str(policy)) == "built-in":
        raise ConfigError("with --resume, only a policy server's new URL", field="--policy")


@dataclass(frozen=True)
class RolloutSummary:
    policy: str
    out: Path
    sheet: Path | None
    asked: int  # episodes the rollout was asked to run
    episodes: int  # of them, with a prediction in `out`
    stopped: int  # predictions whose policy stopped
    steps: int  # actions taken in this run
    seconds: float
    failed: list[tuple[str, str]]  # (episode id, why) the policy failed in this run
    stopped_early: bool  # the failure budget ran out
    preset: list[str]  # what the preset set differently from the defaults
    vocab: str | None = None  # the vocabulary given and the words it lacks

    @property
    def complete(self) -> bool:
        return self.episodes == self.asked

    def lines(self) -> list[str]:
        sheet = f" and {self.sheet}" if self.sheet else ""
        out = [f"preset: {'; '.join(self.preset)}"] if self.preset else []
        out += [self.vocab] if self.vocab else []
        out.append(f"rollout {self.policy}: {self.episodes} of {self.asked} episodes ({self.stopped} stopped by the "
                   f"policy), {self.steps} steps, {self.steps / max(self.seconds, 1e-9):.1f} steps/s -> "
                   f"{self.out}{sheet}")
        out += [f"  FAILED by the policy: {eid}: {why}" for eid, why in self.failed]
        if self.stopped_early:
            out.append(f"stopped: more than the allowed policy failures ({len(self.failed)})")
        if not self.complete:
            out.append(f"{self.asked - self.episodes} episodes to go: sagebench rollout --resume with the same --run "
                       f"and --out runs them")
        return out

    def summary(self) -> str:
        return "\n".join(self.lines())


def sheet_path(out: Path) -> Path:
    return Path(out).with_name(Path(out).stem + "_contact_sheet.png")


def _write_sheet(path: Path, views: list, wanted: int) -> None:
    """The contact sheet, when this process rendered the views of all `wanted` episodes it shows (marked as
    sagebench's, so that a later rollout replaces it)."""
    if views and len(views) == wanted:
        write_bytes(path, marked(cv2.imencode(".png", contact_sheet(views)[:, :, ::-1])[1].tobytes()))


def run_rollout(run_dir: Path, out: Path, config: RolloutConfig = RolloutConfig(), *, scene_id: str | None = None,
                resume: bool = False, force: bool = False, command: str = "rollout") -> RolloutSummary:
    """Roll the policy out over the episodes asked for into `out` (sagebench.navsim.resumable) and write the
    contact sheet; with `resume`, run those an earlier rollout into `out` left, with its settings. `out`, its
    record and its sheet are claimed for `command` first (run_folder.claim_output_file): held by this rollout
    alone, never over a file sagebench did not write unless `force`."""
    out = Path(out)
    sheet = [Output(sheet_path(out), is_marked)] if config.sheet_episodes else []
    with claim_output_file(Output(out, is_rollout_predictions), command, force=force,
                           sidecars=[Output(record_path(out), is_record), *sheet]):
        return _roll_out(Path(run_dir), out, config, scene_id, resume)


def _roll_out(run_dir: Path, out: Path, config: RolloutConfig, scene_id: str | None, resume: bool) -> RolloutSummary:
    share_cores(config.threads)
    earlier = read_record(out) if resume else None
    config = resumed(config, earlier, out) if resume else config
    sim = Simulator(run_dir, config.env, scene_id=scene_id, threads=config.workers)
    asked = earlier.episodes if earlier is not None else select_episodes(
        [sim.episodes[i] for i in sim.order], split=config.split, ids=config.episode_ids, sample=config.episodes,
        seed=config.seed)
    open_inputs(sim, asked, out)
    record = RolloutRecord(policy=config.policy, episodes=asked, observations=observed(sim.sensors, config.policy),
                           success_distance=config.env.success_distance, settings=config.decisive())
    policy = make_policy(config, maps=lambda sid: sim.world(sid).navmap)
    sheet = sheet_path(out)
    start = time.perf_counter()
    try:
        with ui.progress(len(asked), f"rollout {config.policy}") as update:
            def on_step(done: int, steps: int) -> None:
                update(done, f"{steps / max(time.perf_counter() - start, 1e-9):.1f} steps/s")

            one_at_a_time = isinstance(policy, SagePolicy) or (isinstance(policy, VlnceAgents) and not policy.fresh)
            batch = 1 if one_at_a_time else config.batch
            written = run_into(out, sim, policy, record, resume=resume, batch=batch, on_step=on_step,
                               sheet=[] if resume and sheet.exists() else asked[: config.sheet_episodes],
                               max_failures=config.max_policy_failures)
    except KeyboardInterrupt:
        raise Interrupted(f"interrupted: the finished episodes are in {out}; sagebench rollout --resume with the "
                          f"same --run and --out runs the rest") from None
    finally:
        if isinstance(policy, HttpPolicy):
            policy.close()
    result = written.result
    _write_sheet(sheet, result.views, min(config.sheet_episodes, len(asked)))
    return RolloutSummary(policy=config.policy, out=out, sheet=sheet if sheet.exists() else None, asked=len(asked),
                          episodes=len(written.predictions), stopped=sum(p.stopped for p in written.predictions),
                          steps=result.steps, seconds=time.perf_counter() - start, failed=result.failed,
                          stopped_early=result.stopped_early,
                          preset=preset_lines(config, sim, asked), vocab=vocab_line(config, sim, asked))


def preset_lines(config: RolloutConfig, sim: Simulator, asked: list[str]) -> list[str]:
    """What the preset set differently from the defaults, and the body it could not set."""
    if not config.preset:
        return []
    scenes = dict.fromkeys(sim.episodes[i].scene_id for i in asked)
    return [*preset_differences(config.env, EnvConfig()), body_note([sim.world(s).model.agent for s in scenes])]


def vocab_line(config: RolloutConfig, sim: Simulator, asked: list[str]) -> str | None:
    """The vocabulary given (--vocab) and how many tokens of the asked episodes' instructions it lacks (<unk>)."""
    vocab = sim.vocabulary
    if config.env.vocab is None or vocab is None:
        return None
    return vocab.coverage(config.env.vocab, [sim.instructions.get(i, "") for i in asked])


def open_inputs(sim: Simulator, asked: list[str], out: Path) -> None:
    """Every input the rollout reads, read before a byte is written: the asked episodes, their scenes and the goal
    image files they name."""
    gone = [i for i in asked if i not in sim.episodes]
    if gone:
        raise DataError(f"episode {gone[0]!r} of the rollout is not in this run", path=record_path(out))
    for sid in dict.fromkeys(sim.episodes[i].scene_id for i in asked):
        sim.world(sid)
    sim.check_goal_images(asked)


def make_policy(config: RolloutConfig, maps: Callable[[str], NavigableMap] | None = None) -> Policy:
    """The built-in policy the config names (the explorer reads the scenes' maps from `maps`), a VLN-CE agent
    in-process, a SAGE model server's client, or a client of its policy server."""
    kind = policy_kind(config.policy)
    if kind == "built-in":
        return built_in(config.policy, seed=config.seed, actions=config.env.actions, maps=maps)
    if kind == "sage":
        return SagePolicy(config.policy, actions=config.env.actions, replay=config.env.replay,
                          timeout=config.policy_timeout, retries=config.policy_retries)
    if kind == "vlnce":
        spec = AGENT_SPEC.fullmatch(config.policy)
        try:
            agent = getattr(importlib.import_module(spec["module"]), spec["name"])
            return VlnceAgents(agent)
        except (ImportError, AttributeError, ValueError) as err:
            raise ConfigError(f"cannot run {config.policy!r}: {err}", field="--policy") from None
    return HttpPolicy(config.policy, action_space=config.env.action_space, profile=config.env.profile,
                      timeout=config.policy_timeout, retries=config.policy_retries, encoding=config.policy_encoding,
                      workers=config.workers)


def resumed(config: RolloutConfig, earlier: RolloutRecord | None, out: Path) -> RolloutConfig:
    """`config` with the settings of the rollout into `out` being resumed; a policy server may have a new URL."""
    if earlier is None:
        raise ConfigError(f"nothing to resume: no {record_path(out).name} beside {out}", field="--resume")
    policy = earlier.policy
    if policy_kind(config.policy) != "built-in":  # a server's new URL (a built-in given with --resume was refused)
        was, now = client(policy), client(config.policy)
        if was != now:
            raise ConfigError(f"the rollout being resumed ran {was}, not {now}", field="--policy")
        policy = config.policy
    return RolloutConfig.model_validate({**config.model_dump(), **earlier.settings, "policy": policy})


def client(policy: str) -> str:
    """How rollout talks to `policy`, which decides its predictions: a resumed rollout may move to a new URL only
    with the same client (SAGE's endpoint included)."""
    kind = policy_kind(policy)
    if kind == "sage":
        server = sage_server(policy)
        return f"SAGE's {server.transport} client" + (f" on {server.endpoint}" if server.endpoint else "")
    if kind == "http":
        return "a policy server over sagebench's HTTP protocol"
    return f"the VLN-CE agent {policy}" if kind == "vlnce" else f"the built-in policy {policy}"


def observed(sensors: Sensors, policy: str) -> Observed:
    """The record's `observations`: the profile's, plus what a built-in baseline reads of the episode itself."""
    seen = sensors.describe()
    if policy_kind(policy) == "built-in":
        seen["privileged"] = [*seen["privileged"], "episode"]
        seen["keys"]["episode"] = "the goal and the reference path (a built-in baseline)"
    return Observed.model_validate(seen)


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
                 scene_id: str | None = None, force: bool = False) -> BaselineResult:
    """Roll the agent out over every episode of the run (or `scene_id`) and write `out` whole (claimed as
    run_rollout claims it)."""
    done = run_rollout(Path(run_dir), Path(out), config.rollout(), scene_id=scene_id, force=force, command="baseline")
    return BaselineResult(agent_name=config.agent_name, out=done.out, episodes=done.episodes, stopped=done.stopped,
                          actions=done.steps)
