"""A misbehaving OpenAI-compatible chat server on 127.0.0.1 for the LLM tests (threads; no other network).

`FakeLLM(respond)` calls `respond(request_body: dict, n: int) -> Reply` for the n-th request (1-based).
A Reply is a status and body, or a way to misbehave: a non-HTTP line, a truncated body, a body
dripped a byte at a time, or no reply at all. Every handler ends when the server closes.
"""

from __future__ import annotations

import json
import threading
import time
from dataclasses import dataclass, field
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer

MAX_REQUESTS = 200  # a runaway client gets 500s past this, and the test that caused it fails
HANG_S = 30.0  # the longest a handler waits for anything (the server closing ends it sooner)


@dataclass(frozen=True)
class Reply:
    status: int = 200
    body: dict | str | None = None  # a dict becomes a chat-completions reply whose content is its JSON
    headers: dict[str, str] = field(default_factory=dict)
    mode: str = "normal"  # normal | not_http | truncated | drip | hang
    drip_s: float = 0.05  # seconds between bytes in drip mode


def answer(instruction: str) -> Reply:
    return Reply(body={"instruction": instruction})


def completion(content: object) -> dict:
    """A chat-completions reply whose message content is `content` as given (None, a string ...)."""
    return {"choices": [{"index": 0, "message": {"role": "assistant", "content": content}}]}


class FakeLLM:
    def __init__(self, respond, props: dict | None = None):
        self.respond = respond
        self.bodies: list[dict] = []
        self.headers: list[dict[str, str]] = []
        self.in_flight = 0
        self.most_in_flight = 0
        self.dripped = 0  # body bytes sent in drip mode
        self.lock = threading.Lock()
        self.closed = threading.Event()
        fake = self

        class Handler(BaseHTTPRequestHandler):
            def do_GET(self):  # noqa: N802 - a llama.cpp server's GET /props, when `props` is given
                data = json.dumps(props).encode() if props is not None and self.path == "/props" else b"{}"
                self.send_response(200 if props is not None and self.path == "/props" else 404)
                self.send_header("Content-Length", str(len(data)))
                self.end_headers()
                self.wfile.write(data)

            def do_POST(self):  # noqa: N802 (http.server's name)
                length = int(self.headers["Content-Length"])
                raw = self.rfile.read(length)
                if len(raw) < length:  # the client cut the request before its body was out (its breaker cuts
                    return  # the requests in flight): a real server drops it, and no traceback joins the CLI's stderr
                body = json.loads(raw)
                with fake.lock:
                    fake.bodies.append(body)
                    fake.headers.append(dict(self.headers))
                    n = len(fake.bodies)
                    fake.in_flight += 1
                    fake.most_in_flight = max(fake.most_in_flight, fake.in_flight)
                try:
                    reply = Reply(500, "too many requests in a test") if n > MAX_REQUESTS else fake.respond(body, n)
                    self._send(reply)
                except (BrokenPipeError, ConnectionResetError):
                    pass  # the client gave up and left
                finally:
                    with fake.lock:
                        fake.in_flight -= 1

            def _send(self, reply: Reply) -> None:
                if reply.mode == "hang":
                    fake.closed.wait(HANG_S)
                    return
                if reply.mode == "not_http":
                    self.wfile.write(b"HELLO THIS IS NOT HTTP\r\n\r\n")
                    return
                payload = reply.body
                if isinstance(payload, dict) and "choices" not in payload:
                    payload = completion(json.dumps(payload))
                data = (payload if isinstance(payload, str) else json.dumps(payload)).encode()
                self.send_response(reply.status)
                for k, v in reply.headers.items():
                    self.send_header(k, v)
                self.send_header("Content-Length", str(len(data)))
                self.end_headers()
                if reply.mode == "truncated":
                    self.wfile.write(data[: len(data) // 2])
                    self.close_connection = True
                elif reply.mode == "drip":
                    for b in data:
                        if fake.closed.wait(reply.drip_s):
                            return
                        self.wfile.write(bytes([b]))
                        self.wfile.flush()
                        with fake.lock:
                            fake.dripped += 1
                else:
                    self.wfile.write(data)

            def log_message(self, *args):
                pass

        self.server = ThreadingHTTPServer(("127.0.0.1", 0), Handler)
        self.server.daemon_threads = True
        self.url = f"http://127.0.0.1:{self.server.server_address[1]}/v1"
        self.thread = threading.Thread(target=self.server.serve_forever, args=(0.05,), daemon=True)
        self.thread.start()

    @property
    def prompts(self) -> list[str]:
        return [b["messages"][0]["content"] for b in self.bodies]

    def close(self) -> None:
        """Stop listening (later requests are refused) and end every handler still waiting."""
        if not self.closed.is_set():
            self.closed.set()
            self.server.shutdown()
            self.server.server_close()


def bounded(seconds: float, fn, *args, **kwargs):
    """fn(*args, **kwargs) run on a thread: its result (or its exception re-raised), failing the test when it
    has not returned within `seconds` (a guard against hangs, far above the expected time)."""
    out: dict[str, object] = {}

    def run():
        try:
            out["value"] = fn(*args, **kwargs)
        except BaseException as err:  # noqa: BLE001 - handed to the caller
            out["error"] = err

    t = threading.Thread(target=run, daemon=True)
    start = time.monotonic()
    t.start()
    t.join(seconds)
    assert not t.is_alive(), f"still running after {time.monotonic() - start:.1f} s (bound {seconds} s)"
    if "error" in out:
        raise out["error"]  # type: ignore[misc]
    return out["value"]
