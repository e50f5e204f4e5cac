"""VLN-CE's conventions in sagebench's closed loop: the `vlnce` preset (the R2R task's success distance, body and
camera) and an adapter that runs an object with habitat's `Agent` interface (`reset()`, `act(observations) ->
{"action": ...}`) unchanged, in-process (`VlnceAgents`, `sagebench rollout --policy vlnce:MODULE:NAME`) or behind
the policy protocol (`serve`), with the same observations either way.

The agent sees VLN-CE's observation dict: `rgb` [224, 224, 3] uint8, `depth` [256, 256, 1] float32 in [0, 1], and
`instruction` {"text", "tokens" (200 word ids, the run's vocabulary or --vocab's), "trajectory_id"} (the vlnce
profile; its trajectory_id is opaque, like the episode ids a policy server gets), plus `gps` and `compass` when the
rollout gives them. The goal tasks give what habitat-lab's sensors of those tasks give instead of the instruction:
imagenav `imagegoal` [224, 224, 3] uint8 (ImageGoalSensor; sent as rgb is over the protocol), pointnav
`pointgoal_with_gps_compass` [2] float32 [rho, phi] (PointGoalWithGPSCompassSensor, POLAR, 2-D), objectnav
`objectgoal` [1] int64, the category's id in the agent's `category_to_task_category_id` (ObjectGoalSensor's
TASK_CATEGORY_ID: the map of the habitat dataset it was trained on, which export-habitat writes; an agent, or its
class, without one cannot run objectnav). The same arrays in-process and behind the protocol. Its action is VLN-CE's: 0 STOP, 1 MOVE_FORWARD, 2 TURN_LEFT, 3 TURN_RIGHT (sagebench's own ids), as an
int, a name, or {"action": ...} around either, as habitat's Env.step takes it. One agent per running episode:
`make_agent` (a class or a callable) makes it and `reset()` starts its episode; a single agent object runs one
episode at a time.

VLN-CE's R2R task (jacobkrantz/VLN-CE habitat_extensions/config/vlnce_task.yaml over habitat-lab 0.1.7's
defaults): success within 3.0 m of the goal, an agent of radius 0.1 m and height 1.5 m whose RGB and depth
sensors sit 1.25 m up with a 90-degree field of view, RGB 224x224, depth 256x256 normalised over 0-10 m,
MOVE_FORWARD 0.25 m, TURN_LEFT / TURN_RIGHT 15 degrees, 500 steps, instructions tokenized by habitat's tokenize
(sagebench.vlnce.vocab; a pretrained model's own vocabulary: --vocab). The preset sets those that sagebench's
defaults do not already share (sagebench: each episode's goal_radius, 1 m by default; camera 1.2 m; the custom
profile); `preset_differences` lists them for the user. The body is not the env's to set: the closed loop
replays the body the run's maps were built for (AgentConfig, 0.2 m radius, 1.2 m tall by default), so a
benchmark for VLN-CE's body is built for it (`build-scene --agent-radius 0.1 --band-max 1.5`, or a run's
`[build_scene.agent]`).
"""

from __future__ import annotations

import json
import reprlib
import threading
import traceback
from collections import OrderedDict
from collections.abc import Callable, Mapping, Sequence
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from typing import Any

import numpy as np

from sagebench.episodes.episode import Episode
from sagebench.navsim.actions import Action
from sagebench.navsim.opaque import OpaqueIds
from sagebench.navsim.policies import PolicyFailure
from sagebench.navsim.protocol import decode_request
from sagebench.settings.rollout import EnvConfig
from sagebench.settings.shared import AgentConfig, CameraConfig

PRESETS = ("vlnce",)
VLNCE_SUCCESS_DISTANCE = 3.0  # m, vlnce_task.yaml TASK.SUCCESS.SUCCESS_DISTANCE
VLNCE_CAMERA = CameraConfig(height=1.25, hfov_deg=90.0)  # habitat-lab 0.1.7's RGB and depth sensors
VLNCE_BODY = AgentConfig(radius=0.1, height=1.5)  # habitat-lab 0.1.7's SIMULATOR.AGENT_0


def preset_env(name: str) -> dict:
    """The EnvConfig fields a preset sets (a dict to merge under the options given)."""
    if name != "vlnce":
        raise ValueError(f"{name!r} is not a preset (one of {', '.join(PRESETS)})")
    return {"profile": "vlnce", "camera": VLNCE_CAMERA.model_dump(), "success_distance": VLNCE_SUCCESS_DISTANCE,
            "max_steps": 500, "actions": {"forward_step": 0.25, "turn_deg": 15.0}, "tokenizer": "habitat"}


def preset_differences(env: EnvConfig, default: EnvConfig) -> list[str]:
    """What an env config (EnvConfig) sets differently from sagebench's default one: 'name value (default d)'."""
    out = []
    if env.success_distance != default.success_distance:
        out.append(f"success distance {env.success_distance:g} m (default: each episode's goal_radius)")
    for name, label in (("height", "camera height"), ("hfov_deg", "hfov")):
        a, b = getattr(env.camera, name), getattr(default.camera, name)
        if a != b:
            out.append(f"{label} {a:g}{'' if name == 'hfov_deg' else ' m'} (default {b:g})")
    if env.profile != default.profile:
        out.append(f"observations: the {env.profile} profile (default {default.profile})")
    if env.max_steps != default.max_steps:
        out.append(f"max steps {env.max_steps} (default {default.max_steps})")
    if env.tokenizer != default.tokenizer:
        out.append(f"instruction tokens: the {env.tokenizer} tokenizer (default {default.tokenizer})")
    return out


def body_note(bodies: Sequence[AgentConfig]) -> str:
    """The body a rollout replays, set against VLN-CE's: the preset cannot change it (the maps were built for it),
    so the user is told which one the agent drove."""
    said = ", ".join(dict.fromkeys(f"radius {b.radius:g} m, height {b.height:g} m" for b in bodies))
    if all(b.radius == VLNCE_BODY.radius and b.height == VLNCE_BODY.height for b in bodies):
        return f"agent body: the run's maps', {said} (VLN-CE's)"
    return (f"agent body: the run's maps', {said}, not VLN-CE's radius {VLNCE_BODY.radius:g} m, height "
            f"{VLNCE_BODY.height:g} m (build-scene --agent-radius {VLNCE_BODY.radius:g} --band-max "
            f"{VLNCE_BODY.height:g} builds a run for it)")


NEEDED = ("rgb", "depth", "instruction", "instruction_tokens")  # the vlnce profile's keys (a goal task: the images)
LIVE_EPISODES = 1024  # episodes a server keeps, those asked last (one cut by the step limit never says STOP)
MAX_REQUEST_BYTES = 1 << 28  # a request's body: a frame of 4096 x 4096 RGB, depth and instance images fits
MAX_SAID = 300  # characters of an agent's exception message passed on
_SHOWN = reprlib.Repr()  # an agent's reply in a message: a bounded repr that never recurses past maxlevel
_SHOWN.maxlevel, _SHOWN.maxstring, _SHOWN.maxother = 3, 60, 60


GOALS = ("imagegoal", "pointgoal", "objectgoal")  # the goal tasks' keys (sagebench's), given in place of the instruction


def vlnce_observations(obs: Mapping[str, Any], trajectory_id: int,
                       categories: Mapping[str, int] | None = None) -> dict:
    """A vlnce-profile observation (sagebench's keys) as the dict a VLN-CE agent reads: the instruction, or on a
    goal task habitat's goal sensor in its place (module docstring; `categories`: the agent's
    category_to_task_category_id)."""
    goal = next((k for k in GOALS if k in obs), None)
    missing = [k for k in (NEEDED[:2] if goal else NEEDED) if k not in obs]
    if missing:
        raise ValueError(f"a VLN-CE agent needs the vlnce profile's observations (--profile vlnce or --preset "
                         f"vlnce); {missing[0]} is missing")
    out = {"rgb": obs["rgb"], "depth": obs["depth"]}
    if goal is None:
        out["instruction"] = {"text": obs["instruction"], "tokens": [int(t) for t in obs["instruction_tokens"]],
                              "trajectory_id": trajectory_id}
    elif goal == "pointgoal":
        out["pointgoal_with_gps_compass"] = np.asarray(obs["pointgoal"], dtype=np.float32).reshape(2)
    elif goal == "objectgoal":
        out["objectgoal"] = np.array([category_id(obs["objectgoal"], categories)], dtype=np.int64)
    return out | {k: obs[k] for k in ("imagegoal", "gps", "compass") if k in obs}


def category_id(category: str, categories: Mapping[str, int] | None) -> int:
    """habitat's ObjectGoalSensor value of a category: its id in the agent's category_to_task_category_id; a
    ValueError saying why there is none."""
    if categories is None:
        raise ValueError("objectnav gives a VLN-CE agent habitat's objectgoal, the category's id in the agent's "
                         "category_to_task_category_id, and the agent (or its class) has none (export-habitat "
                         "writes the map of a run's categories)")
    if category not in categories:
        raise ValueError(f"the goal category {category!r} is not in the agent's category_to_task_category_id "
                         f"({len(categories)} categories)")
    return int(categories[category])


def agent_categories(agent: Any) -> Mapping[str, int] | None:
    """The agent's (or its class's) category_to_task_category_id: habitat's ObjectNav dataset map it knows."""
    return getattr(agent, "category_to_task_category_id", None)


def vlnce_action(reply: Any) -> Action:
    """An agent's act() result (module docstring) as an action; anything else is a ValueError saying what."""
    a = reply["action"] if isinstance(reply, Mapping) and "action" in reply else reply
    a = a["action"] if isinstance(a, Mapping) and "action" in a else a
    if isinstance(a, str) and a in Action.__members__:
        return Action[a]
    if isinstance(a, int | np.integer) and not isinstance(a, bool) and int(a) in [int(x) for x in Action]:
        return Action(int(a))
    raise ValueError(f"the agent's action {_SHOWN.repr(a)} is not one of VLN-CE's 0 STOP, 1 MOVE_FORWARD, 2 TURN_LEFT, "
                     "3 TURN_RIGHT")


class AgentFailed(Exception):
    """The agent raised, or answered something that is not an action: its episode ends, failed by the policy."""


def agent_answer(agent: Any, observations: dict, *, reset: bool = False) -> Action:
    """The agent's action for `observations` (after its reset() when `reset`); AgentFailed says why there is none,
    naming what the agent raised and where."""
    try:
        if reset:
            agent.reset()
        reply = agent.act(observations)
    except Exception as err:  # noqa: BLE001 - whatever the agent raises ends its episode, visibly
        where = traceback.extract_tb(err.__traceback__)[-1]
        said = str(err)[:MAX_SAID]
        raise AgentFailed(f"the agent raised {type(err).__name__}: {said} (at {where.filename}:{where.lineno})"
                          ) from None
    try:
        return vlnce_action(reply)
    except ValueError as err:
        raise AgentFailed(str(err)) from None


def agent_maker(agent: Any) -> tuple[Callable[[], Any], bool]:
    """(a function making agents, whether it makes a new one each call) for a class, a callable or an object."""
    if isinstance(agent, type) or (callable(agent) and not hasattr(agent, "act")):
        return agent, True
    if hasattr(agent, "act") and hasattr(agent, "reset"):
        return (lambda: agent), False
    raise ValueError(f"{agent!r} has neither habitat's Agent interface (reset, act) nor makes agents")


def trajectory_number(opaque: str) -> int:
    """An opaque per-rollout episode id (hex) as habitat's integer trajectory_id."""
    return int(opaque[:13], 16)


class VlnceAgents:
    """The adapter in-process: a sagebench policy (navsim.policies.Policy) whose episodes each run an agent."""

    def __init__(self, agent: Any):
        self.make, self.fresh = agent_maker(agent)
        self.categories = agent_categories(agent)
        self.opaque_id = OpaqueIds()

    def begin(self, episodes: Sequence[Episode]) -> None:
        if not self.fresh and len(episodes) > 1:
            raise ValueError("a single agent object runs one episode at a time (batch 1); pass its class to run "
                             "several together")
        self.agents = [self.make() for _ in episodes]
        self.started = [False] * len(episodes)
        self.trajectories = [trajectory_number(self.opaque_id(e.episode_id)) for e in episodes]

    def act(self, slots, observations, infos) -> list:
        return [self._answer(i, o) for i, o in zip(slots, observations)]

    def _answer(self, slot: int, obs: dict) -> Action | PolicyFailure:
        """The slot's agent's action (reset first on its first step), or the PolicyFailure ending its episode."""
        reset, self.started[slot] = not self.started[slot], True
        try:
            seen = vlnce_observations(obs, self.trajectories[slot], self.categories)
            return agent_answer(self.agents[slot], seen, reset=reset)
        except (AgentFailed, ValueError) as err:
            return PolicyFailure(str(err))


class Refused(Exception):
    """A request the server answers with an error (`status`, the message) instead of an action."""

    def __init__(self, message: str, status: int = 409):
        super().__init__(message)
        self.status = status


class _Episode:
    """One episode on a server: its agent (None once it has stopped or failed), the step answered last and that
    answer, sent again to a repeat of the step (a retried request whose reply was lost)."""

    def __init__(self, agent: Any, lock: threading.Lock):
        self.agent, self.lock, self.step, self.reply = agent, lock, -1, (0, b"")


class Episodes:
    """The episodes a server runs (`serve`), each request's (episode_id, step) checked against them: step 0 starts
    an episode, each later step follows the one answered last, a repeat of that step gets its answer again without
    the agent acting twice. A single agent object runs one episode at a time: a request for an episode other than
    the one it started last is refused (the first episode's agent was reset under it)."""

    def __init__(self, agent: Any):
        self.make, self.fresh = agent_maker(agent)
        self.categories = agent_categories(agent)
        self.table: OrderedDict[str, _Episode] = OrderedDict()
        self.lock = threading.Lock()
        self.latest: str | None = None  # the episode a single agent object started last
        self.shared = threading.Lock()  # a single agent object's: one of its calls at a time

    def answer(self, fields: dict, images: dict) -> tuple[int, bytes]:
        """(HTTP status, JSON body) for one decoded request."""
        eid, step = fields["episode_id"], fields["step"]
        if not isinstance(eid, str) or not isinstance(step, int) or isinstance(step, bool) or step < 0:
            raise ValueError("episode_id must be a string and step an integer >= 0")
        episode = self._episode(eid, step)
        with episode.lock:
            if step == episode.step:
                return episode.reply
            if episode.agent is None:
                raise Refused(f"episode {eid} has ended (step {episode.step}); step {step} asked")
            if step != episode.step + 1:
                raise Refused(f"episode {eid}: step {step} after step {episode.step}")
            if not self.fresh and self.latest != eid:
                raise Refused(f"episode {eid}: a single agent object runs one episode at a time and episode "
                              f"{self.latest} started after it (run the rollout with --batch 1, or serve the agent's "
                              "class)")
            episode.reply = _act(episode, eid, step, fields, images, self.categories)
            episode.step = step
            return episode.reply

    def _episode(self, eid: str, step: int) -> _Episode:
        with self.lock:
            if eid not in self.table:
                if step != 0:
                    raise Refused(f"episode {eid} is not running on this server (its step 0 was not seen here, or "
                                  f"it was dropped to keep the {LIVE_EPISODES} asked most recently)")
                self.table[eid] = _Episode(self.make(), threading.Lock() if self.fresh else self.shared)
                self.latest = eid
            self.table.move_to_end(eid)  # over the bound, the episode asked least recently goes
            while len(self.table) > LIVE_EPISODES:
                self.table.popitem(last=False)
            return self.table[eid]


def _act(episode: _Episode, eid: str, step: int, fields: dict, images: dict,
         categories: Mapping[str, int] | None) -> tuple[int, bytes]:
    """The agent's answer to one step (resetting it first at step 0); a failed one (AgentFailed) ends the episode:
    HTTP 500 saying why."""
    obs = {**images, **fields, "instruction_tokens": np.asarray(fields.get("instruction_tokens", []), np.int64)}
    seen = vlnce_observations(obs, trajectory_number(eid), categories)
    try:
        action = agent_answer(episode.agent, seen, reset=step == 0)
    except AgentFailed as err:
        episode.agent = None
        return 500, _error(f"{err} (episode {eid}, step {step})")
    if action == Action.STOP:
        episode.agent = None
    return 200, json.dumps({"action": int(action)}).encode()


def _error(message: str) -> bytes:
    return json.dumps({"error": message[:1000]}).encode()


def serve(agent: Any, host: str = "127.0.0.1", port: int = 0) -> ThreadingHTTPServer:
    """A policy server (not yet serving: call its serve_forever) that runs `agent` (module docstring) for the
    requests of a rollout with the vlnce profile (Episodes: one agent per episode when `agent` makes them, a single
    agent object for one episode at a time). A malformed request gets HTTP 400, one out of its episode's order 409,
    one whose agent raised 500, one over MAX_REQUEST_BYTES 413: each with {"error": why}."""
    episodes = Episodes(agent)

    class Handler(BaseHTTPRequestHandler):
        def do_POST(self):  # noqa: N802 - http.server's name
            try:
                status, reply = episodes.answer(*_read_request(self))
            except Refused as err:
                status, reply = err.status, _error(str(err))
            except (ValueError, KeyError, TypeError) as err:
                status, reply = 400, _error(f"{type(err).__name__}: {err}")
            self.send_response(status)
            self.send_header("Content-Type", "application/json")
            self.send_header("Content-Length", str(len(reply)))
            self.end_headers()
            self.wfile.write(reply)

        def log_message(self, *args):
            pass

    server = ThreadingHTTPServer((host, port), Handler)
    server.daemon_threads = True
    return server


def _read_request(handler: BaseHTTPRequestHandler) -> tuple[dict, dict]:
    """(fields, images) of a request, its body bounded by MAX_REQUEST_BYTES and its JSON by MAX_JSON_DEPTH."""
    size = int(handler.headers.get("Content-Length") or -1)
    if not 0 <= size <= MAX_REQUEST_BYTES:
        handler.close_connection = True  # its body is not read
        raise Refused(f"a request's body must have a Content-Length of at most {MAX_REQUEST_BYTES:,} bytes", 413)
    return decode_request(handler.headers.get("Content-Type", ""), handler.rfile.read(size))
