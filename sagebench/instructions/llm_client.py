"""Chat-completions client for OpenAI-compatible servers: bounded in time, retried, cached, and able to give up.

`ChatClient` speaks POST {base_url}/chat/completions with the standard library only (vLLM, a llama.cpp
server, Ollama and OpenAI all serve that route). Every attempt has one deadline for the whole request
(a watchdog cuts the socket, so a server that drips its body cannot stretch it); 429, 5xx, timeouts,
dropped connections, non-HTTP replies and truncated bodies are retried with exponential backoff (a
Retry-After in seconds or as an HTTP date is honoured). A circuit breaker counts consecutive failed
attempts across all threads and, at `breaker_failures`, cuts the requests in flight and refuses new
ones, so a dead, hanging or misconfigured server costs a bounded time. Answers are cached on disk
under sha256 of the model and every generation setting; the server's URL is not in the key.
"""

from __future__ import annotations

import email.utils
import functools
import hashlib
import http.client
import ipaddress
import json
import socket
import threading
import time
import urllib.error
import urllib.parse
import urllib.request
from collections import Counter
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path
from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, field_validator

from sagebench.fileio import dumps_json, write_text

RETRY_STATUS = frozenset({408, 409, 425, 429, 500, 502, 503, 504})
MAX_RETRY_AFTER_S = 30.0
API_KEY_ENV = "SAGEBENCH_LLM_API_KEY"  # the only variable read for the bearer token unless the CLI names another
STOP = ("}",)  # the answer is one flat JSON object: nothing after its closing brace is wanted
ANSWER_SCHEMA = {"type": "object", "properties": {"instruction": {"type": "string"}},
                 "required": ["instruction"], "additionalProperties": False}


class LLMConfig(BaseModel):
    """The chat model and how to call it (defaults here, nowhere else)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    base_url: str | None = Field(default=None, description="OpenAI-compatible API root, e.g. http://localhost:8000/v1.")
    model: str | None = Field(default=None, description="Model name sent with each request.")
    cache_dir: Path | None = Field(default=None, description="Answer cache (default: the user cache directory).")
    concurrency: int = Field(default=4, ge=1, le=64, description="Requests in flight at once.")
    timeout_s: float = Field(default=60.0, gt=0, description="Deadline of one whole HTTP attempt (connect to last byte), s.")
    max_attempts: int = Field(default=3, ge=1, description="HTTP attempts per request (429, 5xx, timeouts retried).")
    backoff_s: float = Field(default=1.0, ge=0, description="First retry delay, s; doubles per attempt.")
    breaker_failures: int = Field(default=6, ge=1,
                                  description="Consecutive failed attempts (all threads) after which no request is sent.")
    answer_attempts: int = Field(default=2, ge=1, description="Answers asked for before the template is kept.")
    temperature: float = Field(default=0.0, ge=0, description="Sampling temperature sent with each request.")
    max_tokens: int = Field(default=200, ge=16, description="Longest answer the server may generate, tokens.")
    response_format: Literal["json_schema", "none"] = Field(
        default="json_schema", description="Ask for JSON by schema (dropped when the server answers 400), or not.")
    prompt_tokens: int = Field(default=3000, ge=500,
                               description="Prompt budget, tokens (estimated); a longer scene map is shortened.")
    min_share: float = Field(default=0.0, ge=0, le=1,
                             description="Fail when fewer high-level rows than this share come from the model "
                                         "(any share fails when none do).")

    @field_validator("base_url")
    @classmethod
    def _http_url(cls, url: str | None) -> str | None:
        parsed = urllib.parse.urlparse(url or "http://x")
        if parsed.scheme not in ("http", "https") or not parsed.hostname:
            raise ValueError(f"must be an http(s) URL such as http://localhost:8000/v1, got {url!r}")
        return url


class LLMError(Exception):
    """A request failed for good (after retries, or with a status not worth retrying)."""


class LLMUnavailable(LLMError):
    """The breaker is open (or the client was cancelled): no request is sent any more."""


def default_cache_dir() -> Path:
    import platformdirs

    return Path(platformdirs.user_cache_dir("sagebench")) / "llm"


def check_cache_dir(path: Path) -> str | None:
    """Why answers cannot be cached under `path` (None when a file can be created there)."""
    try:
        path.mkdir(parents=True, exist_ok=True)
        probe = path / f".probe-{threading.get_ident()}"
        probe.write_bytes(b"")
        probe.unlink()
    except OSError as err:
        return f"cannot write the answer cache: {err.strerror or err}"
    return None


class Breaker:
    """Consecutive failures shared by all threads; opens once at `limit` and stays open."""

    def __init__(self, limit: int):
        self.limit = limit
        self.reason: str | None = None  # why it opened
        self._run = 0
        self._lock = threading.Lock()

    @property
    def is_open(self) -> bool:
        return self.reason is not None

    def success(self) -> None:
        with self._lock:
            self._run = 0

    def failure(self, why: str) -> bool:
        """Count one failure; True exactly once, when this one opens the breaker."""
        with self._lock:
            self._run += 1
            if self.reason is None and self._run >= self.limit:
                self.reason = f"stopped asking after {self._run} consecutive failed requests (last: {why})"
                return True
            return False


class _Watch:
    """One attempt's deadline: at expiry (or on cancel) every socket it saw is shut down, waking blocked reads."""

    def __init__(self, seconds: float):
        self.deadline = time.monotonic() + seconds
        self.expired = False
        self._socks: list[socket.socket] = []
        self._lock = threading.Lock()
        self._timer = threading.Timer(seconds, self.cut)
        self._timer.daemon = True
        self._timer.start()

    def attach(self, sock: socket.socket) -> None:
        with self._lock:
            self._socks.append(sock)
            if self.expired:
                _shut(sock)

    def cut(self) -> None:
        with self._lock:
            self.expired = True
            for s in self._socks:
                _shut(s)

    def stop(self) -> None:
        self._timer.cancel()

    def past(self) -> bool:
        """Cut, or past the deadline (a per-read timeout may fire just before the watchdog does)."""
        return self.expired or time.monotonic() >= self.deadline


def _shut(sock: socket.socket) -> None:
    try:
        sock.shutdown(socket.SHUT_RDWR)
    except OSError:
        pass  # already closed


class _Watched:
    """Connection mixin: hands its socket to the attempt's watch as soon as it is connected."""

    def __init__(self, *args, watch: _Watch, **kwargs):
        self._watch = watch
        super().__init__(*args, **kwargs)

    def connect(self) -> None:
        super().connect()
        self._watch.attach(self.sock)


class _HTTPConnection(_Watched, http.client.HTTPConnection):
    pass


class _HTTPSConnection(_Watched, http.client.HTTPSConnection):
    pass


class _HTTPHandler(urllib.request.HTTPHandler):
    def __init__(self, watch: _Watch):
        super().__init__()
        self.watch = watch

    def http_open(self, req):  # noqa: ANN001, ANN201 - urllib's signature
        return self.do_open(functools.partial(_HTTPConnection, watch=self.watch), req)


class _HTTPSHandler(urllib.request.HTTPSHandler):
    def __init__(self, watch: _Watch):
        super().__init__()
        self.watch = watch

    def https_open(self, req):  # noqa: ANN001, ANN201 - urllib's signature
        return self.do_open(functools.partial(_HTTPSConnection, watch=self.watch), req, context=self._context)


TRANSPORT_ERRORS = (urllib.error.URLError, OSError, http.client.HTTPException)  # BadStatusLine, IncompleteRead ...


class ChatClient:
    """Thread-safe chat-completions client with a disk cache; `stats` counts requests, hits, retries."""

    def __init__(self, config: LLMConfig, *, api_key: str | None = None):
        if not config.base_url or not config.model:
            raise ValueError("LLMConfig needs base_url and model")
        parsed = urllib.parse.urlparse(config.base_url)
        self.config = config
        self.url = config.base_url.rstrip("/") + "/chat/completions"
        self.cache_dir = Path(config.cache_dir) if config.cache_dir is not None else default_cache_dir()
        self.breaker = Breaker(config.breaker_failures)
        self.stats: Counter[str] = Counter()
        self._slots = threading.BoundedSemaphore(config.concurrency)
        self._lock = threading.Lock()
        self._cancelled = threading.Event()
        self._watches: set[_Watch] = set()
        self._schema = config.response_format == "json_schema"  # False once the server refused it
        self._proxies = {} if _is_loopback(parsed.hostname or "") else None  # loopback never goes to a proxy
        self._headers = {"Content-Type": "application/json", **({"Authorization": f"Bearer {api_key}"} if api_key else {})}

    def settings(self) -> dict[str, object]:
        """Everything sent besides the prompt that shapes the answer (the cache key's other half)."""
        cfg = self.config
        return {"model": cfg.model, "temperature": cfg.temperature, "max_tokens": cfg.max_tokens, "stop": list(STOP),
                "response_format": cfg.response_format, "seed": 0}

    def cache_path(self, prompt: str) -> Path:
        key = hashlib.sha256(json.dumps([self.settings(), prompt], sort_keys=True).encode()).hexdigest()
        return self.cache_dir / key[:2] / f"{key}.json"

    def complete(self, prompt: str) -> str:
        """The model's reply to `prompt` (one user message), from the cache when it was asked before."""
        path = self.cache_path(prompt)
        cached = _read_cached(path)
        if cached is not None:
            self._count("cache_hits")
            return cached
        content = self._request(prompt)
        write_text(path, dumps_json({**self.settings(), "prompt": prompt, "content": content}))
        return content

    def cancel(self) -> None:
        """Stop: cut the requests in flight and refuse new ones (Ctrl-C, or the breaker opening)."""
        self._cancelled.set()
        with self._lock:
            watches = list(self._watches)
        for w in watches:
            w.cut()

    def _body(self, prompt: str) -> bytes:
        body: dict[str, object] = {**self.settings(), "messages": [{"role": "user", "content": prompt}]}
        del body["response_format"]
        if self._schema:
            body["response_format"] = {"type": "json_schema",
                                       "json_schema": {"name": "instruction", "strict": True, "schema": ANSWER_SCHEMA}}
        return json.dumps(body).encode()

    def _request(self, prompt: str) -> str:
        cfg = self.config
        last = "no attempt"
        attempt = 0
        while attempt < cfg.max_attempts:
            self._check_open()
            if attempt:
                self._count("retries")
            out = self._attempt(self._body(prompt))
            if out.content is not None:
                return out.content
            last = out.error
            if out.refused_schema:
                continue  # asked again without response_format; not an attempt of its own
            attempt += 1
            if not out.retry:
                raise LLMError(f"{self.url}: {last}")
            if attempt < cfg.max_attempts:
                self._cancelled.wait(max(cfg.backoff_s * 2 ** (attempt - 1), out.wait_s))
        raise LLMError(f"{self.url}: {last} (after {cfg.max_attempts} attempts)")

    def _attempt(self, body: bytes) -> _Outcome:
        """One POST holding a slot; the breaker hears of it before the slot is let go, so at most
        `breaker_failures` failures plus the attempts already in flight are ever sent to a dead server."""
        with self._slots:
            self._check_open()
            out = self._post(body)
            if out.content is not None:
                self.breaker.success()
            elif out.failure and self.breaker.failure(out.error):
                self.cancel()
            return out

    def _post(self, body: bytes) -> _Outcome:
        """POST once under one deadline (the watchdog starts when the request can go out)."""
        watch = _Watch(self.config.timeout_s)
        expired = _Outcome(error=f"no complete reply within {self.config.timeout_s:g} s", retry=True)
        with self._lock:
            self._watches.add(watch)
        try:
            self._count("requests")
            opener = urllib.request.build_opener(urllib.request.ProxyHandler(self._proxies),
                                                 _HTTPHandler(watch), _HTTPSHandler(watch))
            req = urllib.request.Request(self.url, data=body, headers=self._headers, method="POST")
            try:
                with opener.open(req, timeout=self.config.timeout_s) as resp:
                    payload = resp.read()
            except urllib.error.HTTPError as err:
                try:
                    detail = err.read()[:200].decode("utf-8", "replace")
                except TRANSPORT_ERRORS:  # cut while reading the error body
                    detail = ""
                error = _one_line(f"HTTP {err.code} {detail}")
                if err.code == 400 and self._schema:
                    self._schema = False  # the server does not take response_format: ask without it from now on
                    return _Outcome(error=error, failure=False, refused_schema=True)
                return _Outcome(error=error, retry=err.code in RETRY_STATUS, failure=err.code != 429,
                                wait_s=retry_after_s(err.headers.get("Retry-After")))
            except TRANSPORT_ERRORS as err:
                if self._cancelled.is_set():
                    raise LLMUnavailable(self._why_stopped()) from None
                if watch.past():
                    return expired
                return _Outcome(error=_one_line(f"{type(err).__name__}: {getattr(err, 'reason', err)}"), retry=True)
            if watch.expired:  # a body without Content-Length ends at the cut, looking complete
                return expired
            return _content(payload)
        finally:
            watch.stop()
            with self._lock:
                self._watches.discard(watch)

    def _check_open(self) -> None:
        if self._cancelled.is_set():
            raise LLMUnavailable(self._why_stopped())

    def _why_stopped(self) -> str:
        return self.breaker.reason or "cancelled"

    def _count(self, key: str) -> None:
        with self._lock:
            self.stats[key] += 1


@dataclass(frozen=True)
class _Outcome:
    """What one attempt got: the answer's text, or why not and what to do about it."""

    content: str | None = None
    error: str = ""
    retry: bool = False  # worth another attempt (429, 5xx, timeouts, dropped connections)
    failure: bool = True  # counts towards the breaker (a 429 or a refused response_format does not)
    wait_s: float = 0.0  # the server's Retry-After
    refused_schema: bool = False


def _one_line(text: str) -> str:
    """Errors end up in one-line messages: a server's reply may hold newlines."""
    return " ".join(text.split())


def _content(payload: bytes) -> _Outcome:
    """The reply's text, or why it has none (not JSON, not chat-completions, content null): not retried."""
    try:
        message = json.loads(payload)["choices"][0]["message"]
    except (ValueError, KeyError, IndexError, TypeError):
        return _Outcome(error=f"not a chat-completions response: {payload[:200]!r}")
    content = message.get("content") if isinstance(message, dict) else None
    if not isinstance(content, str):
        return _Outcome(error=f"the reply has no text (content {json.dumps(content)}; a reasoning or tool-call reply?)")
    return _Outcome(content=content)


def _read_cached(path: Path) -> str | None:
    """A cached answer's text; None when absent or unusable (it is asked again and overwritten)."""
    try:
        content = json.loads(path.read_text(encoding="utf-8")).get("content")
    except (OSError, ValueError, AttributeError):
        return None
    return content if isinstance(content, str) else None


def _is_loopback(host: str) -> bool:
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def retry_after_s(value: str | None, now: datetime | None = None) -> float:
    """Seconds a Retry-After header asks for (delta-seconds or an HTTP date), clamped to [0, MAX_RETRY_AFTER_S]."""
    if not value:
        return 0.0
    try:
        seconds = float(value)
    except ValueError:
        try:
            when = email.utils.parsedate_to_datetime(value)
        except (TypeError, ValueError, IndexError):
            return 0.0
        if when.tzinfo is None:
            when = when.replace(tzinfo=timezone.utc)
        seconds = (when - (now or datetime.now(timezone.utc))).total_seconds()
    return min(max(seconds, 0.0), MAX_RETRY_AFTER_S)
