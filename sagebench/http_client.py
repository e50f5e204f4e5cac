"""Every outbound HTTP request sagebench makes (the LLM's chat completions, a policy server's actions) goes here.

What each request is promised, whoever makes it:

- One deadline: connecting, sending and reading the whole reply end within `timeout` seconds of the start, or the
  request fails. urllib3's and httpx's timeouts bound each socket operation only (urllib3 says so of its `total`),
  so a server that trickles its reply is never cut by them: `python -m benchmarks http_deadline` measured urllib3
  2.8 (`Timeout(total=2)`, or connect=2, read=2) and httpx2 2.16's `Client(timeout=2)` each reading a 6-byte
  trickle (a byte a second, of the body or of a header line) whole in 6 s, where this client gives up at 2.0 s.
  httpx2's async client under `asyncio.wait_for` holds the deadline too (2.0 s), but only inside an event loop,
  which both callers (blocking code on worker threads, cancelled from the main thread on Ctrl-C) would have to run
  beside them, with httpx2 and its dependencies installed for it. So a watchdog timer shuts the request's socket
  at the deadline (or on `cancel`), waking any blocked read. The transport under it is the standard library's
  urllib.request: urllib3 would add connection reuse but not the deadline, hand the watchdog its sockets only
  through subclassed pool connections, and wrap the exceptions both callers report (and it is not a dependency).
- Retries (`retried`) with exponential backoff, or the server's Retry-After when longer, never sleeping past the
  request's deadline.
- Redirects are not followed (the request, and its Authorization header, would go wherever a reply says): a 3xx
  fails, naming the origin it pointed to.
- A reply's body is at most `max_bytes` (MAX_REPLY_BYTES); JSON is parsed (`parse_json`) only when nested at most
  MAX_JSON_DEPTH deep, so a hostile reply costs neither memory nor a RecursionError.
- No secret in a message: the client's secrets (an API key, the URL's password), and any "Bearer ..." or
  "api_key=..." a server echoes, become [redacted], and messages name the URL without its user:password@.
"""

from __future__ import annotations

import email.utils
import functools
import http.client
import ipaddress
import json
import re
import socket
import threading
import time
import urllib.error
import urllib.parse
import urllib.request
from collections.abc import Callable
from dataclasses import dataclass
from datetime import datetime, timezone
from email.message import Message
from typing import TypeVar

MAX_REPLY_BYTES = 1 << 20
MAX_JSON_DEPTH = 64
MAX_RETRY_AFTER_S = 30.0
REDACTED = "[redacted]"
_BEARER = re.compile(r"(?i)\b(bearer|api[-_ ]?key|authorization)([\s:=\"']+)(?!bearer\b)[^\s\"',;}]+")
# nothing came back, so sending again is safe: refused, reset, closed before a reply, not an HTTP reply, no such host
CONNECTION_ERRORS = (ConnectionError, http.client.RemoteDisconnected, http.client.BadStatusLine, socket.gaierror)
TRANSPORT_ERRORS = (urllib.error.URLError, OSError, http.client.HTTPException)  # IncompleteRead, BadStatusLine ...
T = TypeVar("T")
_STRINGS = re.compile(r'"(?:[^"\\]|\\.)*"', re.S)  # JSON strings, whose brackets do not nest
_BRACKETS = re.compile(r"[\[\]{}]")


class HTTPFailure(Exception):
    """A request that got no usable reply. `kind`: "timeout", "transport" (the connection failed or the reply broke
    off), "redirect", "too large", "cancelled", or a caller's own; `retry`: worth sending again (for
    "transport", only when nothing came back); `wait_s`: how long the server asked to wait first; `cause`: the
    exception the transport raised, as raised."""

    def __init__(self, message: str, *, kind: str, retry: bool = False, wait_s: float = 0.0,
                 cause: BaseException | None = None):
        super().__init__(message)
        self.kind, self.retry, self.wait_s, self.cause = kind, retry, wait_s, cause


class TooDeep(ValueError):
    """JSON nested deeper than MAX_JSON_DEPTH."""


@dataclass(frozen=True)
class Reply:
    """A whole reply (any status but 3xx)."""

    status: int
    reason: str
    headers: Message
    body: bytes


def retried(attempt: Callable[[float | None], T], *, attempts: int, backoff_s: float, timeout: float | None = None,
            wait: Callable[[float], object] | None = None) -> T:
    """attempt(seconds_left) until it returns. An HTTPFailure with `retry` is tried again after backoff_s * 2**n
    (or its `wait_s` when longer) while attempts remain and, with `timeout` (one deadline for all attempts; None:
    each attempt bounds itself and gets None), the wait ends before the deadline; anything else is raised.
    `wait` sleeps (default time.sleep; an Event's wait lets a cancel cut it short)."""
    deadline = None if timeout is None else time.monotonic() + timeout
    for n in range(attempts):
        try:
            return attempt(None if deadline is None else deadline - time.monotonic())
        except HTTPFailure as err:
            pause = max(backoff_s * 2**n, err.wait_s)
            if not err.retry or n + 1 == attempts or (deadline is not None and time.monotonic() + pause >= deadline):
                raise
            (wait or time.sleep)(pause)
    raise ValueError(f"attempts must be at least 1, got {attempts}")


class Client:
    """Requests to one server at `url` (module docstring); thread-safe. `secrets` never show in a message;
    `proxy_from_env`: go through the proxy the environment names (never for a loopback host)."""

    def __init__(self, url: str, *, secrets: tuple[str | None, ...] = (), proxy_from_env: bool = False,
                 max_bytes: int = MAX_REPLY_BYTES):
        parts = urllib.parse.urlsplit(url)
        self.url, self.shown_url, self.max_bytes = url, public_url(url), max_bytes
        self.secrets = tuple(s for s in (*secrets, parts.password) if s)
        self._proxies = None if proxy_from_env and not is_loopback(parts.hostname or "") else {}
        self._lock = threading.Lock()
        self._watches: set[_Watch] = set()
        self._cancelled = False

    def send(self, method: str, url: str | None = None, *, body: bytes | None = None,
             headers: dict[str, str] | None = None, timeout: float) -> Reply:
        """One attempt at `url` (default: the client's) within `timeout` seconds; an HTTPFailure says why not."""
        if timeout <= 0:  # a retry's share of a deadline already spent
            raise HTTPFailure(f"no reply within {timeout:g} s", kind="timeout")
        with self._lock:
            if self._cancelled:
                raise HTTPFailure("cancelled", kind="cancelled")
            watch = _Watch(timeout)
            self._watches.add(watch)
        try:
            req = urllib.request.Request(url or self.url, data=body, headers=headers or {}, method=method)
            reply = self._exchange(req, watch, timeout)
            if watch.expired:  # a body without Content-Length ends at the cut, looking complete
                raise self._failure(TimeoutError(), watch, timeout)
            return reply
        finally:
            watch.stop()
            with self._lock:
                self._watches.discard(watch)

    def cancel(self) -> None:
        """Cut the requests in flight and refuse new ones (Ctrl-C, a breaker opening)."""
        with self._lock:
            self._cancelled = True
            watches = list(self._watches)
        for w in watches:
            w.cut()

    def clean(self, text: str) -> str:
        """`text` fit for a message: one line, no secret, the URL without its user:password@."""
        if self.url != self.shown_url:
            text = text.replace(self.url, self.shown_url)
        return " ".join(redact(text, self.secrets).split())

    def _exchange(self, req: urllib.request.Request, watch: _Watch, timeout: float) -> Reply:
        opener = urllib.request.build_opener(urllib.request.ProxyHandler(self._proxies), _NoRedirect(),
                                             _HTTPHandler(watch), _HTTPSHandler(watch))
        try:
            try:
                resp = opener.open(req, timeout=timeout)
            except urllib.error.HTTPError as err:  # an error status is a reply too
                resp = err
            with resp:
                if 300 <= resp.status < 400:
                    raise HTTPFailure(self.clean(_redirect(resp.status, resp.headers.get("Location"))), kind="redirect")
                raw = resp.fp if isinstance(resp, urllib.error.HTTPError) else resp
                return Reply(resp.status, resp.reason, resp.headers, self._read(raw))
        except TRANSPORT_ERRORS as err:
            raise self._failure(err, watch, timeout) from None

    def _read(self, raw: http.client.HTTPResponse) -> bytes:
        """The whole body (an IncompleteRead when one with a length is cut short), refused past max_bytes."""
        too_large = HTTPFailure(f"the reply is larger than {self.max_bytes:,} bytes", kind="too large")
        if raw.length is not None:  # Content-Length: known before reading
            if raw.length > self.max_bytes:
                raise too_large
            return raw.read()
        data = raw.read(self.max_bytes + 1)
        if len(data) > self.max_bytes:
            raise too_large
        return data

    def _failure(self, err: BaseException, watch: _Watch, timeout: float) -> HTTPFailure:
        cause = err.reason if isinstance(err, urllib.error.URLError) and isinstance(err.reason, BaseException) else err
        if self._cancelled:
            return HTTPFailure("cancelled", kind="cancelled", cause=err)
        if watch.past() or isinstance(cause, TimeoutError):
            return HTTPFailure(f"no reply within {timeout:g} s", kind="timeout", cause=err)
        retry = isinstance(cause, CONNECTION_ERRORS)
        return HTTPFailure(self.clean(f"{type(cause).__name__}: {cause}".rstrip(": ")), kind="transport", retry=retry,
                           cause=err)


def _redirect(status: int, location: str | None) -> str:
    """What a 3xx says: where it points (the origin, or the path of a same-origin Location; never a query)."""
    where = urllib.parse.urlsplit(location or "")
    origin = public_url(f"{where.scheme}://{where.netloc}") if where.netloc else where.path or "no Location given"
    return (f"HTTP {status}: the server redirects to {origin} (redirects are not followed: set the URL to where it "
            "points)")


def parse_json(data: str | bytes) -> object:
    """`data` (UTF-8) parsed as JSON; a TooDeep past MAX_JSON_DEPTH levels of nesting, checked before parsing."""
    text = data.decode("utf-8") if isinstance(data, bytes) else data
    depth = 0
    for bracket in _BRACKETS.findall(_STRINGS.sub("", text)):
        depth += 1 if bracket in "[{" else -1
        if depth > MAX_JSON_DEPTH:
            raise TooDeep(f"the reply's JSON is nested deeper than {MAX_JSON_DEPTH} levels")
    return json.loads(text)


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


def is_loopback(host: str) -> bool:
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


class _Watch:
    """One attempt's deadline, `seconds` from its start: at expiry (or on cancel) every socket it saw is shut down,
    waking blocked reads and writes whatever their own timeouts."""

    def __init__(self, seconds: float):
        self.deadline = time.monotonic() + seconds
        self.expired = False
        self._socks: list[socket.socket] = []
        self._lock = threading.Lock()
        self._timer = threading.Timer(max(seconds, 0.0), self.cut)
        self._timer.daemon = True
        self._timer.start()

    def attach(self, sock: socket.socket) -> None:
        with self._lock:
            self._socks.append(sock)  # held here: a reply that closes its connection takes conn.sock away
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
        """Cut, or past the deadline (a socket timeout may fire just before the watchdog does)."""
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


class _NoRedirect(urllib.request.HTTPRedirectHandler):
    """Redirects are not followed: the 3xx comes back as an HTTPError, which `Client` reports."""

    def redirect_request(self, req, fp, code, msg, headers, newurl):  # noqa: ANN001, ANN201 - urllib's signature
        return None
