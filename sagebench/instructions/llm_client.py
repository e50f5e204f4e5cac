"""Chat-completions client for OpenAI-compatible servers: bounded in time, retried, cached, and able to give up.

`ChatClient` speaks POST {base_url}/chat/completions with the standard library only (vLLM, a llama.cpp
server, Ollama and OpenAI all serve that route). Every attempt has one deadline for the whole request,
counted from when it is sent (a watchdog cuts the socket, so a server that drips its body cannot stretch
it); 429, 5xx, timeouts, dropped connections, non-HTTP replies and truncated bodies are retried with
exponential backoff (a Retry-After in seconds or as an HTTP date is honoured). A circuit breaker counts
consecutive failed attempts across all threads and, at `breaker_failures`, cuts the requests in flight
and refuses new ones, so a dead, hanging or misconfigured server costs a bounded time. Answers are cached
on disk under sha256 of the model and every generation setting; the server's URL is not in the key.

With response_format "auto", the first request decides once, before any other is sent, which way of asking
for JSON the server takes (json_schema, json_object, or none): any 4xx/5xx to one is taken as "not
supported" and the same prompt is sent the next way; so what is asked never depends on timing.

The API key never leaves the request's own origin: redirects are not followed, and the key (and any
"Bearer ..." token) is cut from every server reply before it reaches a message, a log or the cache.
"""

from __future__ import annotations

import email.utils
import functools
import hashlib
import http.client
import ipaddress
import json
import os
import re
import socket
import threading
import time
import urllib.error
import urllib.parse
import urllib.request
from collections import Counter
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path

from sagebench.errors import ConfigError
from sagebench.fileio import dumps_json, write_text
from sagebench.settings.gen_trajectories import LLMConfig

RETRY_STATUS = frozenset({408, 409, 425, 429, 500, 502, 503, 504})
MAX_RETRY_AFTER_S = 30.0
API_KEY_ENV = "SAGEBENCH_LLM_API_KEY"  # the only variable read for the bearer token unless the CLI names another
STOP = ("}",)  # the answer is one flat JSON object: nothing after its closing brace is wanted
ANSWER_SCHEMA = {"type": "object", "properties": {"instruction": {"type": "string"}},
                 "required": ["instruction"], "additionalProperties": False}
FORMATS = ("json_schema", "json_object", "none")  # what response_format "auto" tries, in this order
REMOTE_CONCURRENCY = 4  # requests in flight to a server elsewhere that reports no slots
_BEARER = re.compile(r"(?i)\b(bearer|api[-_ ]?key|authorization)([\s:=\"']+)(?!bearer\b)[^\s\"',;}]+")
REDACTED = "[redacted]"


class LLMError(Exception):
    """A request failed for good (after retries, or with a status not worth retrying)."""


class LLMUnavailable(LLMError):
    """The breaker is open (or the client was cancelled): no request is sent any more."""


def redact(text: str, secrets: tuple[str, ...] = ()) -> str:
    """`text` without the secrets' values or any "Bearer <token>" / "api_key: <token>" it quotes."""
    for secret in secrets:
        if secret:
            text = text.replace(secret, REDACTED)
    return _BEARER.sub(lambda m: f"{m.group(1)}{m.group(2)}{REDACTED}", text)


def public_url(url: str) -> str:
    """`url` without a user:password@ part (a secret, when the URL carries one)."""
    parts = urllib.parse.urlsplit(url)
    if parts.username is None and parts.password is None:
        return url
    host = parts.hostname or ""
    netloc = host if parts.port is None else f"{host}:{parts.port}"
    return urllib.parse.urlunsplit(parts._replace(netloc=netloc))


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


class _Watch:
    """One attempt's deadline, counted from when its request goes out (its socket is connected; connecting is
    bounded by the socket timeout): at expiry (or on cancel) every socket it saw is shut down, waking blocked
    reads. Time spent waiting for a slot in this client is not counted."""

    def __init__(self, seconds: float):
        self.seconds = seconds
        self.deadline: float | None = None
        self.expired = False
        self._socks: list[socket.socket] = []
        self._lock = threading.Lock()
        self._timer: threading.Timer | None = None

    def attach(self, sock: socket.socket) -> None:
        with self._lock:
            self._socks.append(sock)
            if self.expired:
                _shut(sock)
            elif self._timer is None:
                self.deadline = time.monotonic() + self.seconds
                self._timer = threading.Timer(self.seconds, self.cut)
                self._timer.daemon = True
                self._timer.start()

    def cut(self) -> None:
        with self._lock:
            self.expired = True
            for s in self._socks:
                _shut(s)

    def stop(self) -> None:
        with self._lock:
            if self._timer is not None:
                self._timer.cancel()

    def past(self) -> bool:
        """Cut, or past the deadline (a per-read timeout may fire just before the watchdog does)."""
        return self.expired or (self.deadline is not None and time.monotonic() >= self.deadline)


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


class _NoRedirect(urllib.request.HTTPRedirectHandler):
    """Redirects are not followed (the request and its Authorization header would go wherever a reply says):
    the 3xx comes back as an HTTPError naming where it pointed."""

    def redirect_request(self, req, fp, code, msg, headers, newurl):  # noqa: ANN001, ANN201 - urllib's signature
        return None


class ChatClient:
    """Thread-safe chat-completions client with a disk cache; `stats` counts requests, hits, retries."""

    def __init__(self, config: LLMConfig, *, api_key: str | None = None):
        if not config.base_url or not config.model:
            raise ValueError("LLMConfig needs base_url and model")
        parsed = urllib.parse.urlparse(config.base_url)
        self.config = config
        self.url = config.base_url.rstrip("/") + "/chat/completions"
        self.shown_url = public_url(self.url)  # what messages name
        self.cache_dir = Path(config.cache_dir) if config.cache_dir is not None else default_cache_dir()
        self.breaker = Breaker(config.breaker_failures)
        self.stats: Counter[str] = Counter()
        self.concurrency = config.concurrency or 1  # `discover_concurrency` sets the server's when not configured
        self._slots = threading.BoundedSemaphore(self.concurrency)
        self._lock = threading.Lock()
        self._deciding = threading.Lock()  # held while the first request finds the response_format the server takes
        self._cancelled = threading.Event()
        self._watches: set[_Watch] = set()
        self._format: str | None = None if config.response_format == "auto" else config.response_format
        self._proxies = {} if _is_loopback(parsed.hostname or "") else None  # loopback never goes to a proxy
        self._secrets = tuple(x for x in (api_key, parsed.password) if x)
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
        with self._lock:
            watches = list(self._watches)
        for w in watches:
            w.cut()

    def _reported_slots(self) -> int | None:
        root = self.url.removesuffix("/chat/completions").removesuffix("/v1")
        watch = _Watch(min(self.config.timeout_s, 5.0))
        try:
            opener = self._opener(watch)
            req = urllib.request.Request(root + "/props", headers=self._headers, method="GET")
            with opener.open(req, timeout=watch.seconds) as resp:
                slots = json.loads(resp.read(1 << 16)).get("total_slots")
        except (*TRANSPORT_ERRORS, ValueError, AttributeError):
            return None
        finally:
            watch.stop()
        return min(max(slots, 1), 64) if isinstance(slots, int) and not isinstance(slots, bool) else None

    def _opener(self, watch: _Watch) -> urllib.request.OpenerDirector:
        return urllib.request.build_opener(urllib.request.ProxyHandler(self._proxies), _NoRedirect(),
                                           _HTTPHandler(watch), _HTTPSHandler(watch))

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
        last = "no attempt"
        for attempt in range(cfg.max_attempts):
            self._check_open()
            if attempt:
                self._count("retries")
            out = self._attempt(body, refusal_ends)
            if out.content is not None:
                return out.content
            if out.refused:
                raise _Refused(out.error)
            last = out.error
            if not out.retry:
                raise LLMError(f"{self.shown_url}: {last}")
            if attempt + 1 < cfg.max_attempts:
                self._cancelled.wait(max(cfg.backoff_s * 2 ** attempt, out.wait_s))
        raise LLMError(f"{self.shown_url}: {last} (after {cfg.max_attempts} attempts)")

    def _attempt(self, body: bytes, refusal_ends: bool) -> _Outcome:
        """One POST holding a slot; the breaker hears of it before the slot is let go, so at most
        `breaker_failures` failures plus the attempts already in flight are ever sent to a dead server."""
        with self._slots:
            self._check_open()
            out = self._post(body, refusal_ends)
            if out.content is not None:
                self.breaker.success()
            elif out.failure and self.breaker.failure(out.error):
                self.cancel()
            return out

    def _post(self, body: bytes, refusal_ends: bool) -> _Outcome:
        """POST once under one deadline (the watchdog starts when the request goes out). With `refusal_ends`, an
        HTTP error other than 429 is a refusal of the response_format asked for, not a failure."""
        watch = _Watch(self.config.timeout_s)
        expired = _Outcome(error=f"no complete reply within {self.config.timeout_s:g} s", retry=True)
        with self._lock:
            self._watches.add(watch)
        try:
            self._count("requests")
            req = urllib.request.Request(self.url, data=body, headers=self._headers, method="POST")
            try:
                with self._opener(watch).open(req, timeout=self.config.timeout_s) as resp:
                    payload = resp.read()
            except urllib.error.HTTPError as err:
                return self._http_error(err, refusal_ends)
            except TRANSPORT_ERRORS as err:
                if self._cancelled.is_set():
                    raise LLMUnavailable(self._why_stopped()) from None
                if watch.past():
                    return expired
                return _Outcome(error=self._clean(f"{type(err).__name__}: {getattr(err, 'reason', err)}"), retry=True)
            if watch.expired:  # a body without Content-Length ends at the cut, looking complete
                return expired
            out = _content(payload)
            return _Outcome(content=redact(out.content, self._secrets)) if out.content is not None else \
                _Outcome(error=self._clean(out.error)[:300])
        finally:
            watch.stop()
            with self._lock:
                self._watches.discard(watch)

    def _http_error(self, err: urllib.error.HTTPError, refusal_ends: bool) -> _Outcome:
        try:
            detail = err.read(4096).decode("utf-8", "replace")
        except TRANSPORT_ERRORS:  # cut while reading the error body
            detail = ""
        if 300 <= err.code < 400:
            where = urllib.parse.urlsplit(err.headers.get("Location") or "")
            return _Outcome(error=f"HTTP {err.code}: the server redirects to {where.scheme}://{where.netloc} (redirects "
                                  "are not followed: set the base URL to where it points)")
        error = self._clean(f"HTTP {err.code} {detail}")[:200]
        if refusal_ends and err.code != 429:  # counted by the breaker: a server refusing everything is a dead one
            return _Outcome(error=error, refused=True)
        return _Outcome(error=error, retry=err.code in RETRY_STATUS, failure=err.code != 429,
                        wait_s=retry_after_s(err.headers.get("Retry-After")))

    def _clean(self, text: str) -> str:
        """A server's words made fit for a message: one line, no secret."""
        return _one_line(redact(public_url_in(text, self.url, self.shown_url), self._secrets))

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


@dataclass(frozen=True)
class _Outcome:
    """What one attempt got: the answer's text, or why not and what to do about it."""

    content: str | None = None
    error: str = ""
    retry: bool = False  # worth another attempt (429, 5xx, timeouts, dropped connections)
    failure: bool = True  # counts towards the breaker (a 429 does not)
    wait_s: float = 0.0  # the server's Retry-After
    refused: bool = False  # the response_format asked for was refused (while deciding it)


def public_url_in(text: str, url: str, shown: str) -> str:
    """`text` with the client's URL replaced by its public form (a URL's user:password never shows)."""
    return text.replace(url, shown) if url != shown else text


def _one_line(text: str) -> str:
    """Errors end up in one-line messages: a server's reply may hold newlines."""
    return " ".join(text.split())


def _content(payload: bytes) -> _Outcome:
    """The reply's text, or why it has none (not JSON, not chat-completions, content null): not retried."""
    try:
        message = json.loads(payload)["choices"][0]["message"]
    except (ValueError, KeyError, IndexError, TypeError):
        return _Outcome(error=f"not a chat-completions response: {payload[:4096]!r}")
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


def _is_local(host: str) -> bool:
    """On this machine or the local network (loopback, private, link-local, a .local name)."""
    if _is_loopback(host) or host.endswith(".local"):
        return True
    try:
        address = ipaddress.ip_address(host)
    except ValueError:
        return False
    return address.is_private or address.is_link_local


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
