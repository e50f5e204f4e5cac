"""A policy served over HTTP: each step, one POST per running episode (protocol.py); the reply is the action.

Requests go through sagebench.http_client. One deadline per request: connecting, sending and reading the whole
reply must all end within `timeout` seconds of the request's start, or the request fails (a server that answers
one byte a second or never is cut at the deadline, whatever each socket read does). A connection error (refused,
reset, closed before a reply) is retried with exponential backoff from `backoff` seconds while the deadline allows,
at most `retries` times; a retried request carries the same episode_id and step, so a server keeping state can
answer a repeat from its cache. Anything else (a timeout, an HTTP error status, whose JSON {"error": why} the
message quotes, or a redirect, a reply over
http_client's size or nesting bounds or that is not an action) fails the request at once. A failed request fails
its episode only: `act` returns a PolicyFailure in that slot and the rollout records the episode as failed by the
policy.

Episode ids are opaque: each HttpPolicy draws a random key and sends HMAC-SHA256(key, episode_id) (16 hex
digits), so ids are stable within a rollout and say nothing about the run's episodes. Requests for the
episodes of one step go out concurrently on up to `workers` threads; the actions are used in slot order, so the
results do not depend on the thread count.
"""

from __future__ import annotations

from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor

from sagebench.episodes.episode import Episode
from sagebench.http_client import Client, HTTPFailure, parse_json, public_url, retried
from sagebench.navsim.opaque import OpaqueIds
from sagebench.navsim.policies import PolicyFailure
from sagebench.navsim.protocol import encode_request, parse_action, request_fields
from sagebench.settings.rollout import Encoding


MAX_SAID = 300  # characters of a server's error message shown


class RequestFailed(Exception):
    """A request that failed (module docstring); the message says why."""


def post(url: str, body: bytes, content_type: str, *, timeout: float, retries: int = 3, backoff: float = 0.1
         ) -> bytes:
    """The body of a 200 reply to POSTing `body` to `url` (module docstring); RequestFailed says why not."""
    client = Client(url)

    def attempt(seconds_left: float | None) -> bytes:
        reply = client.send("POST", body=body, headers={"Content-Type": content_type}, timeout=seconds_left)
        if reply.status != 200:
            raise HTTPFailure(client.clean(f"HTTP {reply.status} {reply.reason}{said(reply.body)}"), kind="status")
        return reply.body

    try:
        return retried(attempt, attempts=retries + 1, backoff_s=backoff, timeout=timeout)
    except HTTPFailure as err:
        if err.kind == "timeout":
            raise RequestFailed(f"no reply within {timeout:g} s") from None
        raise RequestFailed(f"connection error: {err}" if err.kind == "transport" else str(err)) from None


def said(body: bytes) -> str:
    """What an error reply says, as ': why' (a JSON {"error": why}, its first MAX_SAID characters), or ''."""
    try:
        why = parse_json(body).get("error")
    except (ValueError, AttributeError):
        return ""
    return f": {why[:MAX_SAID]}" if isinstance(why, str) else ""


class HttpPolicy:
    """POSTs observations to `url` (module docstring)."""

    def __init__(self, url: str, *, action_space: str = "discrete", profile: str = "custom", timeout: float = 60.0,
                 workers: int = 1, encoding: Encoding = "raw", retries: int = 3):
        self.url, self.action_space, self.profile, self.timeout = url, action_space, profile, timeout
        self.encoding, self.retries, self.workers = encoding, retries, max(1, workers)
        self.opaque_id = OpaqueIds()  # the id sent for an episode in this rollout
        self._pool = ThreadPoolExecutor(self.workers, thread_name_prefix="policy") if self.workers > 1 else None

    def begin(self, episodes: Sequence[Episode]) -> None:
        self.ids = [self.opaque_id(e.episode_id) for e in episodes]

    def _ask(self, obs: dict, slot: int, step: int):
        where = f"policy {public_url(self.url)} (step {step})"
        fields = request_fields(obs, episode_id=self.ids[slot], step=step, action_space=self.action_space,
                                profile=self.profile)
        content_type, body = encode_request(obs, fields, self.encoding)
        try:
            text = post(self.url, body, content_type, timeout=self.timeout, retries=self.retries)
            return parse_action(parse_json(text), self.action_space)
        except RequestFailed as err:
            return PolicyFailure(f"{where}: {err}")
        except (ValueError, UnicodeDecodeError) as err:
            return PolicyFailure(f"{where}: {err}")

    def act(self, slots, observations, infos) -> list:
        jobs = [(o, i, info["steps"]) for i, o, info in zip(slots, observations, infos)]
        if self._pool is None or len(jobs) == 1:
            return [self._ask(*job) for job in jobs]
        return list(self._pool.map(lambda job: self._ask(*job), jobs))

    def close(self) -> None:
        if self._pool is not None:
            self._pool.shutdown(wait=False, cancel_futures=True)
