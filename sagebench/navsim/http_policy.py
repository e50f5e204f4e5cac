"""A policy served over HTTP: each step, one POST per running episode (protocol.py); the reply is the action.

One deadline per request: connecting, sending the body and reading the whole reply must all end within
`timeout` seconds of the request's start, or the request fails (a server that answers one byte a second or
never is cut at the deadline, whatever each socket read does). A connection error (refused, reset, closed
before a reply) is retried with exponential backoff from `backoff` seconds while the deadline allows, at most
`retries` times; a retried request carries the same episode_id and step, so a server keeping state can answer a
repeat from its cache. Anything else (a timeout, an HTTP error status, a reply that is not an action) fails the
request at once. A failed request fails its episode only: `act` returns a PolicyFailure in that slot and the
rollout records the episode as failed by the policy.

Episode ids are opaque: each HttpPolicy draws a random key and sends HMAC-SHA256(key, episode_id) (16 hex
digits), so ids are stable within a rollout and say nothing about the run's episodes. Requests for the
episodes of one step go out concurrently on up to `workers` threads; the actions are used in slot order, so the
results do not depend on the thread count.
"""

from __future__ import annotations

import hashlib
import hmac
import http.client
import json
import os
import socket
import threading
import time
import urllib.parse
from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor

from sagebench.episodes.episode import Episode
from sagebench.navsim.policies import PolicyFailure
from sagebench.navsim.protocol import encode_request, parse_action, request_fields
from sagebench.settings.rollout import Encoding


class RequestFailed(Exception):
    """A request that failed (module docstring); `retry`: a connection error, worth another attempt."""

    def __init__(self, reason: str, *, retry: bool = False):
        super().__init__(reason)
        self.retry = retry


_CONNECTION_ERRORS = (ConnectionError, http.client.RemoteDisconnected, http.client.BadStatusLine, socket.gaierror)


def post(url: str, body: bytes, content_type: str, *, timeout: float, retries: int = 3, backoff: float = 0.1
         ) -> bytes:
    """The body of a 200 reply to POSTing `body` to `url` (module docstring); RequestFailed says why not."""
    parts = urllib.parse.urlsplit(url)
    deadline = time.monotonic() + timeout
    for attempt in range(retries + 1):
        try:
            return _attempt(parts, body, content_type, deadline, timeout)
        except RequestFailed as err:
            wait = backoff * 2**attempt
            if not err.retry or attempt == retries or time.monotonic() + wait >= deadline:
                raise
            time.sleep(wait)
    raise AssertionError("unreachable")


def _attempt(parts: urllib.parse.SplitResult, body: bytes, content_type: str, deadline: float, timeout: float
             ) -> bytes:
    remaining = deadline - time.monotonic()
    if remaining <= 0:
        raise RequestFailed(f"no reply within {timeout:g} s")
    kind = http.client.HTTPSConnection if parts.scheme == "https" else http.client.HTTPConnection
    conn = kind(parts.hostname, parts.port, timeout=remaining)
    cut = threading.Event()
    socks: list[socket.socket] = []

    def watchdog() -> None:  # ends a request still in flight at the deadline, however its socket reads go
        cut.set()
        for sock in socks:
            try:
                sock.shutdown(socket.SHUT_RDWR)
            except OSError:
                pass

    timer = threading.Timer(remaining, watchdog)
    timer.daemon = True
    timer.start()
    path = (parts.path or "/") + (f"?{parts.query}" if parts.query else "")
    try:
        conn.connect()
        # held here: a reply that closes the connection takes conn.sock away while its body is still being read
        socks.append(conn.sock)
        if cut.is_set():  # the watchdog fired before there was a socket to cut
            raise TimeoutError
        conn.request("POST", path, body=body, headers={"Content-Type": content_type})
        resp = conn.getresponse()
        data = resp.read()
    except (TimeoutError, socket.timeout):
        raise RequestFailed(f"no reply within {timeout:g} s") from None
    except (*_CONNECTION_ERRORS, OSError, http.client.HTTPException) as err:
        if cut.is_set():
            raise RequestFailed(f"no reply within {timeout:g} s") from None
        retry = isinstance(err, _CONNECTION_ERRORS)
        raise RequestFailed(f"connection error: {err.__class__.__name__}: {err}".rstrip(": "), retry=retry) from None
    finally:
        timer.cancel()
        conn.close()
    if cut.is_set():
        raise RequestFailed(f"no reply within {timeout:g} s")
    if resp.status != 200:
        raise RequestFailed(f"HTTP {resp.status} {resp.reason}")
    return data


class HttpPolicy:
    """POSTs observations to `url` (module docstring)."""

    def __init__(self, url: str, *, action_space: str = "discrete", profile: str = "custom", timeout: float = 60.0,
                 workers: int = 1, encoding: Encoding = "raw", retries: int = 3):
        self.url, self.action_space, self.profile, self.timeout = url, action_space, profile, timeout
        self.encoding, self.retries, self.workers = encoding, retries, max(1, workers)
        self._key = os.urandom(16)
        self._pool = ThreadPoolExecutor(self.workers, thread_name_prefix="policy") if self.workers > 1 else None

    def opaque_id(self, episode_id: str) -> str:
        """The id sent for `episode_id` in this rollout."""
        return hmac.new(self._key, episode_id.encode("utf-8"), hashlib.sha256).hexdigest()[:16]

    def begin(self, episodes: Sequence[Episode]) -> None:
        self.ids = [self.opaque_id(e.episode_id) for e in episodes]

    def _ask(self, obs: dict, slot: int, step: int):
        where = f"policy {self.url} (step {step})"
        fields = request_fields(obs, episode_id=self.ids[slot], step=step, action_space=self.action_space,
                                profile=self.profile)
        content_type, body = encode_request(obs, fields, self.encoding)
        try:
            text = post(self.url, body, content_type, timeout=self.timeout, retries=self.retries)
            return parse_action(json.loads(text.decode("utf-8")), self.action_space)
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
