"""What every outbound request is promised (sagebench/http_client.py), against raw servers on 127.0.0.1 that send
exactly the bytes a test gives them, as slowly as it says: one deadline per request however the reply trickles,
retries that never sleep past the deadline (on a fake clock), no redirect followed, a bound on the reply's size
and on its JSON's nesting, and no secret in any message."""

from __future__ import annotations

import ast
import re
import socket
import threading
import types
from pathlib import Path

import pytest
from fake_llm import bounded

import sagebench
import sagebench.http_client as http_client
from sagebench.http_client import MAX_JSON_DEPTH, Client, HTTPFailure, TooDeep, parse_json, retried

KEY = "sk-test-9d8c7b6a5f4e3d2c1b0a"
HEAD = b"HTTP/1.1 200 OK\r\nContent-Type: application/json\r\n"


class RawServer:
    """Answers each connection with `reply`: a list of (bytes, seconds to wait before sending them); counts the
    requests it read and the reply bytes it sent. Closes the connection after the reply."""

    def __init__(self, reply: list[tuple[bytes, float]]):
        self.reply, self.requests, self.sent = reply, [], 0
        self.closed = threading.Event()
        self.sock = socket.create_server(("127.0.0.1", 0))
        self.origin = f"http://127.0.0.1:{self.sock.getsockname()[1]}"
        threading.Thread(target=self._serve, daemon=True).start()

    def _serve(self) -> None:
        while not self.closed.is_set():
            try:
                conn, _ = self.sock.accept()
            except OSError:
                return
            threading.Thread(target=self._answer, args=(conn,), daemon=True).start()

    def _answer(self, conn: socket.socket) -> None:
        with conn:
            data = b""
            while b"\r\n\r\n" not in data and (chunk := conn.recv(65536)):
                data += chunk
            length = re.search(rb"(?i)\r\ncontent-length: *(\d+)", data)
            while length and len(data.partition(b"\r\n\r\n")[2]) < int(length[1]) and (chunk := conn.recv(65536)):
                data += chunk  # the whole body: closing with unread bytes would reset the connection
            self.requests.append(data.decode("latin-1"))
            try:
                for part, wait in self.reply:
                    if self.closed.wait(wait):
                        return
                    conn.sendall(part)
                    self.sent += len(part)
            except OSError:
                pass  # the client gave up

    def close(self) -> None:
        self.closed.set()
        self.sock.close()


@pytest.fixture
def serve():
    made: list[RawServer] = []

    def start(*parts: bytes | tuple[bytes, float]) -> RawServer:
        made.append(RawServer([p if isinstance(p, tuple) else (p, 0.0) for p in parts]))
        return made[-1]

    yield start
    for s in made:
        s.close()


def trickle(data: bytes, every_s: float = 0.1) -> list[tuple[bytes, float]]:
    return [(bytes([b]), every_s) for b in data]


@pytest.mark.parametrize("part", ["headers", "body"])
def test_a_reply_trickled_a_byte_at_a_time_is_cut_at_the_deadline(serve, part):
    """A byte every 0.1 s keeps every socket read inside its own timeout; the 3 s reply outlasts the 0.5 s deadline
    sixfold, so a client bounding each read only would read it whole and return it."""
    if part == "headers":
        server = serve(HEAD + b"Content-Length: 2\r\n", *trickle(b"X-Slow: " + b"." * 30 + b"\r\n"), b"\r\n{}")
    else:
        server = serve(HEAD + b"Content-Length: 30\r\n\r\n", *trickle(b" " * 28 + b"{}"))
    with pytest.raises(HTTPFailure, match=r"^no reply within 0.5 s$") as err:
        bounded(10.0, Client(server.origin).send, "GET", timeout=0.5)
    assert err.value.kind == "timeout" and not err.value.retry


def test_a_hung_request_is_cut_when_cancelled_and_no_other_is_sent(serve):
    server = serve((b"", 30.0))
    client = Client(server.origin)
    outcome: list[HTTPFailure] = []
    thread = threading.Thread(target=lambda: outcome.append(pytest.raises(HTTPFailure, client.send, "GET",
                                                                          timeout=60.0).value))
    thread.start()
    bounded(10.0, lambda: [threading.Event().wait(0.01) for _ in iter(lambda: bool(server.requests), True)])
    client.cancel()
    bounded(10.0, thread.join)
    with pytest.raises(HTTPFailure, match="^cancelled$"):
        client.send("GET", timeout=60.0)
    assert outcome[0].kind == "cancelled" and len(server.requests) == 1


@pytest.fixture
def fake_clock(monkeypatch):
    """http_client's clock and sleep, where sleeping only moves the clock on: what the tests measure is the
    client's arithmetic, not the machine's speed."""
    slept: list[float] = []
    clock = types.SimpleNamespace(monotonic=lambda: 1000.0 + sum(slept), sleep=slept.append)
    monkeypatch.setattr(http_client, "time", clock)
    return slept


def failing(*failures: HTTPFailure):
    """An attempt that raises the failures given in turn (the last one for ever), counting its calls."""
    calls: list[float | None] = []

    def attempt(seconds_left):
        calls.append(seconds_left)
        raise failures[min(len(calls), len(failures)) - 1]

    return attempt, calls


def test_retries_back_off_doubling_and_never_sleep_past_the_deadline(fake_clock):
    """A 1 s deadline, backoff from 0.2 s: attempts at 0, 0.2 and 0.6 s; the next wait (0.8 s) would end at 1.4 s,
    past the deadline, so the request fails there rather than sleep."""
    attempt, calls = failing(HTTPFailure("refused", kind="transport", retry=True))
    with pytest.raises(HTTPFailure, match="^refused$"):
        retried(attempt, attempts=10, backoff_s=0.2, timeout=1.0)
    assert fake_clock == [0.2, 0.4] and calls == pytest.approx([1.0, 0.8, 0.4])


def test_a_retry_after_past_the_deadline_is_not_waited_for(fake_clock):
    attempt, calls = failing(HTTPFailure("HTTP 429", kind="status", retry=True, wait_s=30.0))
    with pytest.raises(HTTPFailure, match="^HTTP 429$"):
        retried(attempt, attempts=5, backoff_s=0.1, timeout=10.0)
    assert fake_clock == [] and len(calls) == 1


def test_without_a_deadline_retries_take_the_longer_of_backoff_and_retry_after(fake_clock):
    attempt, calls = failing(HTTPFailure("HTTP 503", kind="status", retry=True, wait_s=0.5),
                             HTTPFailure("reset", kind="transport", retry=True))
    with pytest.raises(HTTPFailure, match="^reset$"):
        retried(attempt, attempts=4, backoff_s=0.1)
    assert fake_clock == [0.5, 0.2, 0.4] and calls == [None] * 4


def test_a_failure_not_worth_retrying_is_raised_at_once(fake_clock):
    attempt, calls = failing(HTTPFailure("IncompleteRead", kind="transport"))
    with pytest.raises(HTTPFailure, match="^IncompleteRead$"):
        retried(attempt, attempts=5, backoff_s=0.1, timeout=10.0)
    assert fake_clock == [] and len(calls) == 1


@pytest.mark.parametrize("reply, retry", [
    (b"", True),  # closed before a reply: nothing came back, sending again is safe
    (HEAD + b"Content-Length: 10\r\n\r\n{}", False),  # the reply broke off: the server has acted on the request
])
def test_only_a_request_that_got_nothing_back_is_worth_sending_again(serve, reply, retry):
    with pytest.raises(HTTPFailure) as err:
        Client(serve(reply).origin).send("POST", body=b"{}", timeout=10.0)
    assert (err.value.kind, err.value.retry) == ("transport", retry)


def test_a_redirect_is_not_followed_and_names_where_it_pointed(serve):
    elsewhere = serve(HEAD + b"Content-Length: 2\r\n\r\n{}")
    server = serve(b"HTTP/1.1 307 Temporary Redirect\r\nLocation: " + elsewhere.origin.encode() + b"/v1/x?token="
                   + KEY.encode() + b"\r\nContent-Length: 0\r\n\r\n")
    with pytest.raises(HTTPFailure) as err:
        Client(server.origin, secrets=(KEY,)).send("POST", body=b"{}", headers={"Authorization": f"Bearer {KEY}"},
                                                   timeout=10.0)
    assert str(err.value) == (f"HTTP 307: the server redirects to {elsewhere.origin} (redirects are not followed: set "
                              "the URL to where it points)")
    assert err.value.kind == "redirect" and elsewhere.requests == [] and len(server.requests) == 1


@pytest.mark.parametrize("framing", ["content-length", "chunked", "until-close"])
def test_a_reply_over_the_size_bound_is_refused(serve, framing):
    body = b"[" + b"0," * 600 + b"0]"  # 1,203 bytes
    head = {"content-length": b"Content-Length: %d\r\n\r\n" % len(body),
            "chunked": b"Transfer-Encoding: chunked\r\n\r\n", "until-close": b"\r\n"}[framing]
    payload = b"%x\r\n%s\r\n0\r\n\r\n" % (len(body), body) if framing == "chunked" else body
    server = serve(HEAD + head + payload)
    with pytest.raises(HTTPFailure, match=r"^the reply is larger than 1,024 bytes$") as err:
        Client(server.origin, max_bytes=1024).send("GET", timeout=10.0)
    assert err.value.kind == "too large" and not err.value.retry
    assert Client(server.origin, max_bytes=2048).send("GET", timeout=10.0).body == body


def test_json_nested_past_the_bound_is_refused_before_parsing():
    deep = "[" * (MAX_JSON_DEPTH + 1) + "]" * (MAX_JSON_DEPTH + 1)
    with pytest.raises(TooDeep, match=f"^the reply's JSON is nested deeper than {MAX_JSON_DEPTH} levels$"):
        parse_json(deep.encode())
    with pytest.raises(TooDeep):
        parse_json("[" * 100_000)  # what json.loads answers with a RecursionError
    assert parse_json(deep[1:-1]) == parse_json(deep[1:-1].encode())
    brackets_in_strings = '{"a": "' + "[{" * MAX_JSON_DEPTH + '", "b": "\\"[[[", "c": [[1]]}'
    assert parse_json(brackets_in_strings)["c"] == [[1]]


def test_no_secret_reaches_a_message(serve):
    """The key echoed in a reply that is not HTTP, and the password in the client's URL, never show."""
    server = serve(b"HELLO Authorization: Bearer " + KEY.encode() + b" and " + KEY[::-1].encode() + b"\r\n\r\n")
    client = Client(server.origin + "/v1", secrets=(KEY[::-1],))
    with pytest.raises(HTTPFailure) as err:
        client.send("GET", timeout=10.0)
    assert err.value.kind == "transport" and err.value.retry  # BadStatusLine: nothing HTTP came back
    assert str(err.value) == "BadStatusLine: HELLO Authorization: Bearer [redacted] and [redacted]"
    url = server.origin.replace("http://", "http://user:hunter2@") + "/v1"
    assert Client(url).clean(f"{url} answered: password=hunter2") == f"{server.origin}/v1 answered: password=[redacted]"


def test_no_other_module_sends_http_requests():
    """The promises above hold for a request only if it goes through this client: no other module of the package
    imports an HTTP client library."""
    clients = ("urllib.request", "http.client", "urllib3", "httpx", "httpx2", "requests", "aiohttp")
    root = Path(sagebench.__file__).parent
    found = set()
    for path in root.rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            names = [a.name for a in node.names] if isinstance(node, ast.Import) else \
                [node.module or ""] if isinstance(node, ast.ImportFrom) else []
            found |= {(path.relative_to(root).as_posix(), n) for n in names if n.startswith(clients)}
    assert {where for where, _ in found} == {"http_client.py"}, sorted(found)
