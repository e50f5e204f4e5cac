"""VLN-CE's conventions in sagebench's closed loop: the `vlnce` preset (the R2R task's success distance, body and
camera) and an adapter that runs an object with habitat's `Agent` interface (`reset()`, `act(observations) ->
{"action": ...}`) unchanged, in-process (`VlnceAgents`, `sagebench rollout --policy vlnce:MODULE:NAME`) or behind
the policy protocol (`serve`), with the same observations either way.

The agent sees VLN-CE's observation dict: `rgb` [224, 224, 3] uint8, `depth` [256, 256, 1] float32 in [0, 1], and
`instruction` {"text", "tokens" (200 word ids, the run's vocabulary), "trajectory_id"} (the vlnce profile; its
trajectory_id is opaque, like the episode ids a policy server gets), plus `gps` and `compass` when the rollout
gives them. Its action is VLN-CE's: 0 STOP, 1 MOVE_FORWARD, 2 TURN_LEFT, 3 TURN_RIGHT (sagebench's own ids), as an
int, a name, or {"action": ...} around either, as habitat's Env.step takes it. One agent per running episode:
`make_agent` (a class or a callable) makes it and `reset()` starts its episode; a single agent object runs one
episode at a time.

VLN-CE's R2R task (jacobkrantz/VLN-CE habitat_extensions/config/vlnce_task.yaml over habitat-lab 0.1.7's
defaults): success within 3.0 m of the goal, an agent of radius 0.1 m and height 1.5 m whose RGB and depth
sensors sit 1.25 m up with a 90-degree field of view, RGB 224x224, depth 256x256 normalised over 0-10 m,
MOVE_FORWARD 0.25 m, TURN_LEFT / TURN_RIGHT 15 degrees, 500 steps. The preset sets those that sagebench's
defaults do not already share (sagebench: each episode's goal_radius, 1 m by default; camera 1.2 m; the custom
profile); `preset_differences` lists them for the user. The body is not the env's to set: the closed loop
replays the body the run's maps were built for (AgentConfig, 0.2 m radius, 1.2 m tall by default), so a
benchmark for VLN-CE's body is built for it (`build-scene --agent-radius 0.1 --band-max 1.5`, or a run's
`[build_scene.agent]`).
"""

from __future__ import annotations

import hashlib
import hmac
import json
import os
import threading
from collections import OrderedDict
from collections.abc import Callable, Mapping, Sequence
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from typing import Any

import numpy as np

from sagebench.episodes.episode import Episode
from sagebench.navsim.actions import Action
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
            "max_steps": 500, "actions": {"forward_step": 0.25, "turn_deg": 15.0}}


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


NEEDED = ("rgb", "depth", "instruction", "instruction_tokens")  # the vlnce profile's keys
LIVE_AGENTS = 1024  # agents a server keeps, the most recently asked (an episode cut by the step limit never says STOP)


def vlnce_observations(obs: Mapping[str, Any], trajectory_id: int) -> dict:
    """A vlnce-profile observation (sagebench's keys) as the dict a VLN-CE agent reads."""
    missing = [k for k in NEEDED if k not in obs]
    if missing:
        raise ValueError(f"a VLN-CE agent needs the vlnce profile's observations (--profile vlnce or --preset "
                         f"vlnce); {missing[0]} is missing")
    out = {"rgb": obs["rgb"], "depth": obs["depth"],
           "instruction": {"text": obs["instruction"], "tokens": [int(t) for t in obs["instruction_tokens"]],
                           "trajectory_id": trajectory_id}}
    return out | {k: obs[k] for k in ("gps", "compass") if k in obs}


def vlnce_action(reply: Any) -> Action:
    """An agent's act() result (module docstring) as an action; anything else is a ValueError saying what."""
    a = reply["action"] if isinstance(reply, Mapping) and "action" in reply else reply
    a = a["action"] if isinstance(a, Mapping) and "action" in a else a
    if isinstance(a, str) and a in Action.__members__:
        return Action[a]
    if isinstance(a, int | np.integer) and not isinstance(a, bool) and int(a) in [int(x) for x in Action]:
        return Action(int(a))
    raise ValueError(f"the agent's action {a!r} is not one of VLN-CE's 0 STOP, 1 MOVE_FORWARD, 2 TURN_LEFT, "
                     "3 TURN_RIGHT")


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
        self._key = os.urandom(16)

    def begin(self, episodes: Sequence[Episode]) -> None:
        if not self.fresh and len(episodes) > 1:
            raise ValueError("a single agent object runs one episode at a time (batch 1); pass its class to run "
                             "several together")
        self.agents = [self.make() for _ in episodes]
        for a in self.agents:
            a.reset()
        self.trajectories = [trajectory_number(hmac.new(self._key, e.episode_id.encode(), hashlib.sha256).hexdigest())
                             for e in episodes]

    def act(self, slots, observations, infos) -> list:
        return [vlnce_action(self.agents[i].act(vlnce_observations(o, self.trajectories[i])))
                for i, o in zip(slots, observations)]


def serve(agent: Any, host: str = "127.0.0.1", port: int = 0) -> ThreadingHTTPServer:
    """A policy server (not yet serving: call its serve_forever) that runs `agent` (module docstring) for the
    requests of a rollout with the vlnce profile, one agent per episode id, made and reset at step 0 (a single
    agent object serves a rollout run with --batch 1). A request it cannot answer gets HTTP 400 and why."""
    make, fresh = agent_maker(agent)
    agents: OrderedDict[str, tuple[Any, threading.Lock]] = OrderedDict()
    lock = threading.Lock()

    class Handler(BaseHTTPRequestHandler):
        def do_POST(self):  # noqa: N802 - http.server's name
            try:
                body = self.rfile.read(int(self.headers["Content-Length"]))
                fields, images = decode_request(self.headers.get("Content-Type", ""), body)
                eid = fields["episode_id"]
                with lock:
                    new = fields["step"] == 0 or eid not in agents
                    if new:
                        agents[eid] = (make(), threading.Lock())
                    agents.move_to_end(eid)  # over the bound, the agent asked least recently goes
                    while len(agents) > LIVE_AGENTS:
                        agents.popitem(last=False)
                    one, mine = agents[eid]
                obs = {**images, **fields, "instruction_tokens": np.asarray(fields.get("instruction_tokens", []),
                                                                             np.int64)}
                with mine:
                    if new:
                        one.reset()
                    action = vlnce_action(one.act(vlnce_observations(obs, trajectory_number(eid))))
                if action == Action.STOP:
                    with lock:
                        agents.pop(eid, None)
                reply, status = json.dumps({"action": int(action)}).encode(), 200
            except (ValueError, KeyError, TypeError) as err:
                reply, status = json.dumps({"error": str(err)}).encode(), 400
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
