"""Chat-completions client for OpenAI-compatible servers: bounded in time, retried, cached, and able to give up.

`ChatClient` speaks POST {base_url}/chat/completions through sagebench.http_client (vLLM, a llama.cpp server,
Ollama and OpenAI all serve that route). Every attempt has one deadline for the whole request (a server that
drips its body cannot stretch it); 429, 5xx, timeouts, dropped connections, non-HTTP replies and truncated
bodies are retried with exponential backoff (a Retry-After in seconds or as an HTTP date is honoured). A circuit
breaker counts consecutive failed attempts across all threads and, at `breaker_failures`, cuts the requests in
flight and refuses new ones, so a dead, hanging or misconfigured server costs a bounded time. Answers are cached
on disk under sha256 of the model and every generation setting; the server's URL is not in the key.

With response_format "auto", the first request decides once, before any other is sent, which way of asking
for JSON the server takes (json_schema, json_object, or none): any 4xx/5xx to one is taken as "not
supported" and the same prompt is sent the next way; so what is asked never depends on timing.

The API key never leaves the request's own origin: redirects are not followed, and the key (and any
"Bearer ..." token) is cut from every server reply before it reaches a message, a log or the cache; the
environment's proxy is used for a server that is not on this machine.
"""

from __future__ import annotations

import hashlib
import ipaddress
import itertools
import json
import os
import re
import threading
import urllib.parse
from collections import Counter
from collections.abc import Callable, Mapping
from pathlib import Path

from sagebench.errors import ConfigError
from sagebench.fileio import dumps_json, write_text
from sagebench.http_client import (
    Client,
    HTTPFailure,
    Reply,
    TooDeep,
    is_loopback,
    parse_json,
    redact,
    retried,
    retry_after_s,
)
from sagebench.settings.gen_trajectories import LLMConfig

RETRY_STATUS = frozenset({408, 409, 425, 429, 500, 502, 503, 504})
API_KEY_ENV = "SAGEBENCH_LLM_API_KEY"  # the only variable read for the bearer token unless the CLI names another
STOP = ("}",)  # the answer is one flat JSON object: nothing after its closing brace is wanted
ANSWER_SCHEMA = {"type": "object", "properties": {"instruction": {"type": "string"}},
                 "required": ["instruction"], "additionalProperties": False}
FORMATS = ("json_schema", "json_object", "none")  # what response_format "auto" tries, in this order
REMOTE_CONCURRENCY = 4  # requests in flight to a server elsewhere that reports no slots


class LLMError(Exception):
    """A request failed for good (after retries, or with a status not worth retrying)."""


class LLMUnavailable(LLMError):
    """The breaker is open (or the client was cancelled): no request is sent any more."""


_ENV_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")


def api_key_from_env(name: str, environ: Mapping[str, str]) -> str:
    """The key in the environment variable `name`. A ConfigError when `name` is not a variable's name (it looks
    like the key itself, which the message then does not repeat) or the variable is not set."""
    looks_like_key = not _ENV_NAME.fullmatch(name) or (
        len(name) >= 20 and any(c.islower() for c in name) and any(c.isdigit() for c in name))
    if looks_like_key:
        raise ConfigError("takes the name of an environment variable holding the key (letters, digits and _), not the "
                          "key itself; the value given is not shown", field="--llm-api-key-env")
    if name not in environ:
        raise ConfigError(f"the environment variable {name} is not set", field="--llm-api-key-env")
    return environ[name]


def default_cache_dir() -> Path:
    import platformdirs

    return Path(platformdirs.user_cache_dir("sagebench")) / "llm"


def check_cache_dir(path: Path) -> str | None:
    """Why answers cannot be cached under `path` (None when a file can be created there)."""
    try:
        path.mkdir(parents=True, exist_ok=True)
        probe = path / f".probe-{os.getpid()}-{threading.get_ident()}"
        os.close(os.open(probe, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW | os.O_CLOEXEC, 0o600))
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


class ChatClient:
    """Thread-safe chat-completions client with a disk cache; `stats` counts requests, hits, retries."""

    def __init__(self, config: LLMConfig, *, api_key: str | None = None):
        if not config.base_url or not config.model:
            raise ValueError("LLMConfig needs base_url and model")
        self.config = config
        self.url = config.base_url.rstrip("/") + "/chat/completions"
        self.http = Client(self.url, secrets=(api_key,), proxy_from_env=True)
        self.shown_url = self.http.shown_url  # what messages name
        self.cache_dir = Path(config.cache_dir) if config.cache_dir is not None else default_cache_dir()
        self.breaker = Breaker(config.breaker_failures)
        self.stats: Counter[str] = Counter()
        self.concurrency = config.concurrency or 1  # `discover_concurrency` sets the server's when not configured
        self._slots = threading.BoundedSemaphore(self.concurrency)
        self._lock = threading.Lock()
        self._deciding = threading.Lock()  # held while the first request finds the response_format the server takes
        self._cancelled = threading.Event()
        self._format: str | None = None if config.response_format == "auto" else config.response_format
        self._headers = {"Content-Type": "application/json", **({"Authorization": f"Bearer {api_key}"} if api_key else {})}

    def settings(self) -> dict[str, object]:
        """Everything sent besides the prompt that shapes the answer (the cache key's other half)."""
        cfg = self.config
        return {"model": cfg.model, "temperature": cfg.temperature, "max_tokens": cfg.max_tokens, "stop": list(STOP),
                "response_format": cfg.response_format, "seed": 0}

    def cache_path(self, prompt: str) -> Path:
        key = hashlib.sha256(json.dumps([self.settings(), prompt], sort_keys=True).encode()).hexdigest()
        return self.cache_dir / key[:2] / f"{key}.json"

    @property
    def response_format(self) -> str | None:
        """The way JSON is asked for, once decided (None while "auto" has sent nothing)."""
        return self._format

    def complete(self, prompt: str, *, keep: Callable[[str], bool] | None = None) -> str:
        """The model's reply to `prompt` (one user message), from the cache when it was asked before (unless
        `refresh`). A reply is cached only when `keep(reply)` (default: always), so an answer of the wrong form
        is asked again next time rather than forever read back."""
        path = self.cache_path(prompt)
        cached = None if self.config.refresh else _read_cached(path)
        if cached is not None:
            self._count("cache_hits")
            return cached
        content = self._request(prompt)
        if keep is None or keep(content):
            write_text(path, dumps_json({**self.settings(), "prompt": prompt, "content": content}))
        return content

    def discover_concurrency(self) -> int:
        """Set and return the requests in flight: the configured number, else the slots the server reports
        (llama.cpp's GET /props `total_slots`), else 1 for a server on this machine or the local network (one
        that answers one request at a time would keep the others queued past their deadline), else
        REMOTE_CONCURRENCY."""
        if self.config.concurrency is None:
            host = urllib.parse.urlparse(self.url).hostname or ""
            self.concurrency = self._reported_slots() or (1 if _is_local(host) else REMOTE_CONCURRENCY)
            self._slots = threading.BoundedSemaphore(self.concurrency)
        return self.concurrency

    def cancel(self) -> None:
        """Stop: cut the requests in flight and refuse new ones (Ctrl-C, or the breaker opening)."""
        self._cancelled.set()
        self.http.cancel()

    def _reported_slots(self) -> int | None:
        root = self.url.removesuffix("/chat/completions").removesuffix("/v1")
        try:
            reply = self.http.send("GET", root + "/props", headers=self._headers,
                                   timeout=min(self.config.timeout_s, 5.0))
            slots = parse_json(reply.body).get("total_slots") if reply.status == 200 else None
        except (HTTPFailure, ValueError, AttributeError):
            return None
        return min(max(slots, 1), 64) if isinstance(slots, int) and not isinstance(slots, bool) else None

    def _body(self, prompt: str, fmt: str) -> bytes:
        body: dict[str, object] = {**self.settings(), "messages": [{"role": "user", "content": prompt}]}
        del body["response_format"]
        if fmt == "json_schema":
            body["response_format"] = {"type": "json_schema",
                                       "json_schema": {"name": "instruction", "strict": True, "schema": ANSWER_SCHEMA}}
        elif fmt == "json_object":
            body["response_format"] = {"type": "json_object"}
        return json.dumps(body).encode()

    def _request(self, prompt: str) -> str:
        """The answer to `prompt`; while "auto" is undecided, the first caller tries each format in turn with this
        prompt and the others wait for its decision."""
        if self._format is None:
            with self._deciding:
                if self._format is None:
                    return self._decide(prompt)
        return self._ask(prompt, self._format)

    def _decide(self, prompt: str) -> str:
        for fmt in FORMATS[:-1]:
            try:
                content = self._ask(prompt, fmt, refusal_ends=True)
            except _Refused:
                self._count("formats_refused")
                continue
            self._format = fmt
            return content
        content = self._ask(prompt, FORMATS[-1])
        self._format = FORMATS[-1]
        return content

    def _ask(self, prompt: str, fmt: str, *, refusal_ends: bool = False) -> str:
        cfg = self.config
        body = self._body(prompt, fmt)
        tries = itertools.count()

        def attempt(_: float | None) -> str:
            self._check_open()
            if next(tries):
                self._count("retries")
            return self._attempt(body, refusal_ends)

        try:
            return retried(attempt, attempts=cfg.max_attempts, backoff_s=cfg.backoff_s, wait=self._cancelled.wait)
        except _Failed as err:
            if err.refused:
                raise _Refused(str(err)) from None
            after = f" (after {cfg.max_attempts} attempts)" if err.retry else ""  # else not worth another
            raise LLMError(f"{self.shown_url}: {err}{after}") from None

    def _attempt(self, body: bytes, refusal_ends: bool) -> str:
        """One POST holding a slot; the breaker hears of it before the slot is let go, so at most
        `breaker_failures` failures plus the attempts already in flight are ever sent to a dead server."""
        with self._slots:
            self._check_open()
            try:
                content = self._post(body, refusal_ends)
            except _Failed as err:
                if err.counts and self.breaker.failure(str(err)):
                    self.cancel()
                raise
            self.breaker.success()
            return content

    def _post(self, body: bytes, refusal_ends: bool) -> str:
        """POST once under one deadline: the answer's text, or a _Failed saying why not. With `refusal_ends`, an
        HTTP error other than 429 is a refusal of the response_format asked for, not a failure."""
        self._count("requests")
        try:
            reply = self.http.send("POST", body=body, headers=self._headers, timeout=self.config.timeout_s)
        except HTTPFailure as err:
            raise self._transport_failure(err) from None
        if not 200 <= reply.status < 300:
            raise self._http_error(reply, refusal_ends)
        try:
            return redact(_content(reply.body), self.http.secrets)
        except ValueError as err:
            raise _Failed(self.http.clean(str(err))[:300]) from None

    def _transport_failure(self, err: HTTPFailure) -> Exception:
        """What an attempt that got no reply means here: timeouts and broken connections are retried."""
        if err.kind == "cancelled":
            return LLMUnavailable(self._why_stopped())
        if err.kind == "timeout":
            return _Failed(f"no complete reply within {self.config.timeout_s:g} s", retry=True)
        if err.kind == "transport":
            cause = err.cause
            return _Failed(self.http.clean(f"{type(cause).__name__}: {getattr(cause, 'reason', cause)}"), retry=True)
        return _Failed(str(err))  # a redirect, a reply too large

    def _http_error(self, reply: Reply, refusal_ends: bool) -> _Failed:
        detail = reply.body[:4096].decode("utf-8", "replace")
        error = self.http.clean(f"HTTP {reply.status} {detail}")[:200]
        if refusal_ends and reply.status != 429:  # counted by the breaker: a server refusing everything is a dead one
            return _Failed(error, refused=True)
        return _Failed(error, retry=reply.status in RETRY_STATUS, counts=reply.status != 429,
                       wait_s=retry_after_s(reply.headers.get("Retry-After")))

    def _check_open(self) -> None:
        if self._cancelled.is_set():
            raise LLMUnavailable(self._why_stopped())

    def _why_stopped(self) -> str:
        return self.breaker.reason or "cancelled"

    def _count(self, key: str) -> None:
        with self._lock:
            self.stats[key] += 1


class _Refused(Exception):
    """The server answered a request asking for one response_format with an HTTP error: try the next."""


class _Failed(HTTPFailure):
    """An attempt that got no answer; `counts` towards the breaker (a 429 does not); `refused`: the response_format
    asked for was refused (while deciding it)."""

    def __init__(self, message: str, *, retry: bool = False, wait_s: float = 0.0, counts: bool = True,
                 refused: bool = False):
        super().__init__(message, kind="llm", retry=retry, wait_s=wait_s)
        self.counts, self.refused = counts, refused


def _content(payload: bytes) -> str:
    """The reply's text; a ValueError says why it has none (not JSON, not chat-completions, content null)."""
    try:
        message = parse_json(payload)["choices"][0]["message"]
    except TooDeep:
        raise
    except (ValueError, KeyError, IndexError, TypeError):
        raise ValueError(f"not a chat-completions response: {payload[:4096]!r}") from None
    content = message.get("content") if isinstance(message, dict) else None
    if not isinstance(content, str):
        raise ValueError(f"the reply has no text (content {json.dumps(content)}; a reasoning or tool-call reply?)")
    return content


def _read_cached(path: Path) -> str | None:
    """A cached answer's text; None when absent or unusable (it is asked again and overwritten)."""
    try:
        content = json.loads(path.read_text(encoding="utf-8")).get("content")
    except (OSError, ValueError, AttributeError):
        return None
    return content if isinstance(content, str) else None


def _is_local(host: str) -> bool:
    """On this machine or the local network (loopback, private, link-local, a .local name)."""
    if is_loopback(host) or host.endswith(".local"):
        return True
    try:
        address = ipaddress.ip_address(host)
    except ValueError:
        return False
    return address.is_private or address.is_link_local
