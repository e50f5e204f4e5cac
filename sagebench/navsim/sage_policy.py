"""A SAGE-Bench model server as a rollout policy: `sage+http://HOST:PORT[/vln_step|/nogoal_step]` or
`sage+socket://HOST:PORT`, spoken to as SAGE-3D's vlm_client_modular.py speaks (navsim/sage_protocol.py).

- sage+http://HOST:PORT (or .../vln_step): SAGE's rgb + text + http client, POST /vln_step with the current frame;
- sage+http://HOST:PORT/nogoal_step: its rgbd + trajectory + http client (NavDP / NoMaD-style servers); when the
  port is 8888 (SAGE's rule) POST /navigator_reset with SAGE's camera intrinsics first, once per episode;
- sage+socket://HOST:PORT: its rgb + text + socket client (NaVILA, NaVid, MLLM servers), the episode's last 8 frames.

Each answer is parsed as SAGE's parsers do into a 1 s command, then driven in the continuous action space as
SAGE's env.apply_cmd_for moves: the forward translation first, then the turn, each split into as few control
intervals as the agent's speed and turn-rate limits allow (the server is asked again once the command is done). A
reply that is not what SAGE's servers send fails the episode with one line naming the server and what is wrong
(SAGE's client would stop or move on silently); docs/sage_models.md lists every choice.
"""

from __future__ import annotations

import json
import math
import os
import urllib.parse
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass

from sagebench.episodes.episode import Episode
from sagebench.http_client import MAX_REPLY_BYTES, parse_json, public_url
from sagebench.navsim.framed_socket import SocketFailure, exchange
from sagebench.navsim.http_policy import RequestFailed, post
from sagebench.navsim.policies import PolicyFailure
from sagebench.navsim.sage_protocol import (
    Command, History, nogoal_step_body, parse_text, parse_trajectory, reply_text, socket_frame, trajectory_points,
    vln_step_body,
)
from sagebench.settings.shared import ActionConfig, ReplayConfig

SCHEMES = ("sage+http://", "sage+socket://")
ENDPOINTS = ("/vln_step", "/nogoal_step")
NAVDP_PORT = 8888
NAVDP_RESET = {"intrinsic": [[525.0, 0.0, 320.0], [0.0, 525.0, 240.0], [0.0, 0.0, 1.0]], "stop_threshold": -0.5,
               "batch_size": 1}


@dataclass(frozen=True)
class SageServer:
    """Where a sage+ URL points and how SAGE's client talks to it there."""

    url: str
    transport: str  # "http" or "socket"
    host: str
    port: int
    endpoint: str | None  # the HTTP endpoint; None on the socket

    @property
    def depth(self) -> bool:
        return self.endpoint == "/nogoal_step"

    def http_url(self, path: str) -> str:
        return f"http://{self.host}:{self.port}{path}"


def sage_server(url: str) -> SageServer:
    """The server a sage+http:// or sage+socket:// URL names; a ValueError says what is wrong with it."""
    if not url.startswith(SCHEMES):
        raise ValueError(f"{url!r} is not a sage+http:// or sage+socket:// URL")
    parts = urllib.parse.urlsplit(url.removeprefix("sage+"))
    try:
        port = parts.port
    except ValueError:
        port = None
    if not parts.hostname or port is None or parts.query or parts.fragment or parts.username:
        raise ValueError(f"{public_url(url)!r} must be sage+{parts.scheme}://HOST:PORT")
    path = parts.path.rstrip("/")
    if parts.scheme == "socket" and path:
        raise ValueError(f"SAGE's socket protocol has no endpoint: sage+socket://HOST:PORT, not {path!r}")
    if parts.scheme == "http" and path and path not in ENDPOINTS:
        raise ValueError(f"SAGE's HTTP endpoints are {' and '.join(ENDPOINTS)}, not {path!r}")
    endpoint = (path or ENDPOINTS[0]) if parts.scheme == "http" else None
    return SageServer(url, parts.scheme, parts.hostname, port, endpoint)


class BadReply(ValueError):
    """A reply SAGE's servers would not send (or no reply): the message says what."""


def motion_plan(command: Command, interval: float, replay: ReplayConfig) -> list[tuple[list[float], int]]:
    """(continuous action [v, omega, stop], intervals) segments driving `command`: translation, then turn (module
    docstring). The body has no sideways or backward drive: vy and a negative vx move it nowhere (documented)."""
    if command.stop:
        return [([0.0, 0.0, 1.0], 1)]
    if not all(math.isfinite(x) for x in (command.vx, command.vy, command.yaw_rate)):
        raise BadReply("its answer asks for a motion that is not finite")
    plan = []
    for amount, limit, axis in ((max(command.vx, 0.0) * command.duration_s, replay.max_speed, 0),
                                (command.yaw_rate * command.duration_s, replay.max_turn_rate, 1)):
        if amount:
            n = max(1, math.ceil(abs(amount) / (limit * interval) - 1e-9))
            action = [0.0, 0.0, 0.0]
            action[axis] = amount / (n * interval)
            plan.append((action, n))
    return plan or [([0.0, 0.0, 0.0], 1)]


class SagePolicy:
    """A SAGE model server (module docstring); one episode at a time, as SAGE runs them."""

    def __init__(self, url: str, *, actions: ActionConfig = ActionConfig(), replay: ReplayConfig = ReplayConfig(),
                 timeout: float = 60.0, retries: int = 3):
        self.server = sage_server(url)
        self.interval, self.replay, self.timeout, self.retries = actions.control_interval, replay, timeout, retries

    def begin(self, episodes: Sequence[Episode]) -> None:
        self.histories = [History() for _ in episodes]
        self.plans: list[deque] = [deque() for _ in episodes]
        self.reset = [self.server.depth and self.server.port == NAVDP_PORT] * len(episodes)

    def act(self, slots, observations, infos) -> list:
        return [self._next(slot, obs, info["steps"]) for slot, obs, info in zip(slots, observations, infos)]

    def _next(self, slot: int, obs: dict, step: int):
        plan = self.plans[slot]
        if not plan:
            try:
                plan.extend([list(segment) for segment in motion_plan(self._ask(slot, obs), self.interval,
                                                                       self.replay)])
            except BadReply as err:
                why = " ".join(str(err).split())
                return PolicyFailure(f"SAGE model server {public_url(self.server.url)} (step {step}): {why}")
        action, _ = plan[0]
        plan[0][1] -= 1
        if not plan[0][1]:
            plan.popleft()
        return list(action)

    def _ask(self, slot: int, obs: dict) -> Command:
        if self.server.transport == "socket":
            frame = socket_frame(self.histories[slot].add(obs["rgb"]), obs["instruction"])
            return parse_text(reply_text(socket_reply(self._exchange(frame))))
        if not self.server.depth:
            reply = self._post(ENDPOINTS[0], vln_step_body(obs["rgb"], obs["instruction"]), "application/json")
            if not isinstance(reply, dict) or not isinstance(reply.get("result"), str):
                raise BadReply('/vln_step answered no {"result": text} (SAGE\'s client would move forward)')
            return parse_text(reply_text({"text": reply["result"]}))
        if self.reset[slot]:
            self.reset[slot] = False
            self._post("/navigator_reset", json.dumps(NAVDP_RESET).encode("utf-8"), "application/json", expect_json=False)
        content_type, body = nogoal_step_body(obs["rgb"], obs["depth"], os.urandom(16).hex())
        reply = self._post(ENDPOINTS[1], body, content_type)
        if not isinstance(reply, dict) or "trajectory" not in reply:
            raise BadReply('/nogoal_step answered no {"trajectory": [[x, y, z], ...]}')
        try:
            return parse_trajectory(trajectory_points(reply["trajectory"]))
        except ValueError as err:
            raise BadReply(f"/nogoal_step's reply: {err}") from None

    def _post(self, path: str, body: bytes, content_type: str, *, expect_json: bool = True) -> object:
        try:
            text = post(self.server.http_url(path), body, content_type, timeout=self.timeout, retries=self.retries)
        except RequestFailed as err:
            raise BadReply(f"{path}: {err}") from None
        return _json_reply(text, path) if expect_json else None

    def _exchange(self, frame: bytes) -> bytes:
        try:
            return exchange(self.server.host, self.server.port, frame, timeout=self.timeout, retries=self.retries,
                            max_bytes=MAX_REPLY_BYTES)
        except SocketFailure as err:
            raise BadReply(str(err)) from None


def socket_reply(payload: bytes) -> object:
    """A socket reply as SAGE's servers send it: the model's text (NaVILA) or an object holding it ("result":
    the MLLM server, "text_response": NaVid's); an object with status "error" is the server's own failure."""
    reply = _json_reply(payload, "the socket")
    if isinstance(reply, dict) and reply.get("status") == "error":
        raise BadReply(f"the server reports an error: {str(reply.get('message', 'no message'))[:200]}")
    if isinstance(reply, str) or (isinstance(reply, dict) and ("result" in reply or "text_response" in reply)):
        return reply
    raise BadReply("its reply is neither text nor an object with \"result\" or \"text_response\"")


def _json_reply(data: bytes, where: str) -> object:
    try:
        return parse_json(data)
    except (ValueError, UnicodeDecodeError) as err:
        raise BadReply(f"{where}'s reply is not JSON ({str(err)[:120]})") from None
