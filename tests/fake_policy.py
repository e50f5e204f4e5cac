"""A policy server on 127.0.0.1 for the closed-loop tests: a deterministic policy that reads depth, and faults on
the requests chosen (every fault ends on its own within a minute, so no test can hang on it)."""

from __future__ import annotations

import json
import threading
import time
from collections.abc import Callable
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer

import numpy as np

from sagebench.navsim.protocol import decode_request

FAULTS = ("status500", "drip", "hang", "close", "truncated", "deep")
LONGEST_FAULT = 60.0  # s: a hanging or dripping reply gives up after this
DRIP_S = 0.2  # s between dripped bytes: well inside any read timeout, so only a request's deadline ends a drip


def decide(fields: dict, images: dict[str, np.ndarray]) -> str:
    """STOP after 5 steps; turn left when something is closer than 0.5 m ahead, else move forward (an action of
    what the request holds only, so a rerun of an episode gets the same answers)."""
    if fields["step"] >= 5:
        return "STOP"
    depth = images.get("depth")
    if depth is not None:
        d = depth.reshape(depth.shape[0], depth.shape[1])
        ahead = d[d.shape[0] // 2, d.shape[1] // 3: 2 * d.shape[1] // 3]
        return "TURN_LEFT" if 0 < ahead.min() < 0.5 else "MOVE_FORWARD"
    return "MOVE_FORWARD" if fields["step"] % 3 else "TURN_LEFT"


class FakePolicy:
    """Serves `decide` at `url` (or, `continuous`, v 0.3 m/s straight on until step 3, then stop); `fault` (one of
    FAULTS) answers the requests `faulty(n)` picks (n counts from 1)."""

    def __init__(self, fault: str | None = None, faulty: Callable[[int], bool] = lambda n: True, *,
                 continuous: bool = False):
        self.fault, self.faulty, self.continuous = fault, faulty, continuous
        self.requests = 0
        self.seen: list[tuple[dict, dict[str, np.ndarray]]] = []
        self._lock, self._stop = threading.Lock(), threading.Event()
        owner = self

        class Handler(BaseHTTPRequestHandler):
            def do_POST(self):  # noqa: N802 - http.server's name
                body = self.rfile.read(int(self.headers["Content-Length"]))
                with owner._lock:
                    owner.requests += 1
                    n = owner.requests
                fault = owner.fault if owner.fault and owner.faulty(n) else None
                if fault == "close":
                    self.close_connection = True
                    return
                if fault == "hang":
                    owner._stop.wait(LONGEST_FAULT)
                    return
                if fault == "status500":
                    self.send_error(500, "policy crashed")
                    return
                fields, images = decode_request(self.headers["Content-Type"], body)
                with owner._lock:
                    owner.seen.append((fields, images))
                action = [0.3, 0.0, float(fields["step"] >= 3)] if owner.continuous else decide(fields, images)
                reply = json.dumps({"action": action}).encode()
                if fault == "deep":  # an action nested 100,000 lists deep (json.loads: RecursionError)
                    reply = b'{"action": ' + b"[" * 100_000 + b"]" * 100_000 + b"}"
                if fault == "drip":  # valid JSON whose whitespace tail outlasts LONGEST_FAULT at DRIP_S a byte
                    reply += b" " * int(LONGEST_FAULT / DRIP_S)
                self.send_response(200)
                self.send_header("Content-Type", "application/json")
                # truncated: the policy decided, and its reply ends before the length it announced
                self.send_header("Content-Length", str(len(reply) + 10 * (fault == "truncated")))
                self.end_headers()
                if fault == "truncated":
                    self.close_connection = True
                if fault == "drip":  # a byte every DRIP_S until the client gives up (or LONGEST_FAULT)
                    start = time.monotonic()
                    for byte in reply:
                        if self._stopped(start):
                            return
                        self.wfile.write(bytes([byte]))
                        self.wfile.flush()
                        time.sleep(DRIP_S)
                    return
                self.wfile.write(reply)

            def _stopped(self, start: float) -> bool:
                return owner._stop.is_set() or time.monotonic() - start > LONGEST_FAULT

            def log_message(self, *args):
                pass

            def handle(self):
                try:
                    super().handle()
                except (BrokenPipeError, ConnectionResetError):  # the client cut a faulty reply at its deadline
                    pass

        self.server = ThreadingHTTPServer(("127.0.0.1", 0), Handler)
        self.server.daemon_threads = True
        self.thread = threading.Thread(target=self.server.serve_forever, daemon=True)
        self.thread.start()
        self.url = f"http://127.0.0.1:{self.server.server_address[1]}/act"

    def close(self) -> None:
        self._stop.set()
        self.server.shutdown()
        self.server.server_close()
        self.thread.join(timeout=10)
