"""Can a client hold one deadline for a whole HTTP request? Each client asks a server on 127.0.0.1 that trickles
its reply a byte a second (the headers, or the body after prompt headers), so no per-read timeout ever fires;
a client holds the deadline when it gives up within DEADLINE_S (+0.5 s) instead of reading the whole trickle.
The measurement behind sagebench/http_client.py's choice: urllib3 and httpx2's blocking client bound each socket
operation only; httpx2's async client under a cancel scope holds it, and so does a watchdog that shuts the socket.
"""

from __future__ import annotations

import asyncio
import socket
import threading
import time

DEADLINE_S = 2.0
TRICKLE = b"abcdef"  # a byte a second: the whole reply takes len(TRICKLE) s
HEAD = b"HTTP/1.1 200 OK\r\nContent-Type: text/plain\r\nContent-Length: %d\r\n"


class TrickleServer:
    """Answers every request slowly: part "headers" drips an extra header line, part "body" drips the body."""

    def __init__(self, part: str):
        self.part = part
        self.sock = socket.create_server(("127.0.0.1", 0))
        self.url = f"http://127.0.0.1:{self.sock.getsockname()[1]}/"
        threading.Thread(target=self._serve, daemon=True).start()

    def _serve(self) -> None:
        while True:
            try:
                conn, _ = self.sock.accept()
            except OSError:
                return
            threading.Thread(target=self._answer, args=(conn,), daemon=True).start()

    def _answer(self, conn: socket.socket) -> None:
        with conn:
            conn.recv(65536)
            if self.part == "headers":
                fast, tail = HEAD % 2 + b"X-Slow: ", b"\r\n\r\nok"
            else:
                fast, tail = HEAD % len(TRICKLE) + b"\r\n", b""
            try:
                conn.sendall(fast)
                for byte in TRICKLE:
                    time.sleep(1.0)
                    conn.sendall(bytes([byte]))
                conn.sendall(tail)
            except OSError:
                pass  # the client gave up

    def close(self) -> None:
        self.sock.close()


def _urllib3_total(url: str) -> None:
    import urllib3

    urllib3.PoolManager().request("GET", url, timeout=urllib3.Timeout(total=DEADLINE_S), retries=False)


def _urllib3_connect_read(url: str) -> None:
    import urllib3

    urllib3.PoolManager().request("GET", url, timeout=urllib3.Timeout(connect=DEADLINE_S, read=DEADLINE_S),
                                  retries=False)


def _httpx2_sync(url: str) -> None:
    import httpx2

    with httpx2.Client(timeout=DEADLINE_S, trust_env=False) as client:
        client.get(url)


def _httpx2_async(url: str) -> None:
    import httpx2

    async def get() -> None:
        async with httpx2.AsyncClient(timeout=DEADLINE_S, trust_env=False) as client:
            await asyncio.wait_for(client.get(url), DEADLINE_S)

    asyncio.run(get())


def _sagebench(url: str) -> None:
    from sagebench.http_client import Client

    Client(url).send("GET", timeout=DEADLINE_S)


CLIENTS = {"urllib3 Timeout(total=2)": _urllib3_total, "urllib3 Timeout(connect=2, read=2)": _urllib3_connect_read,
           "httpx2.Client(timeout=2)": _httpx2_sync, "httpx2.AsyncClient + asyncio.wait_for(2)": _httpx2_async,
           "sagebench.http_client (watchdog)": _sagebench}


def run() -> list[dict]:
    rows = []
    for part in ("body", "headers"):
        server = TrickleServer(part)
        for name, ask in CLIENTS.items():
            start = time.monotonic()
            try:
                ask(server.url)
                outcome = "read the whole trickle"
            except ImportError:  # urllib3 and httpx2 come with the test extra's packages, not with sagebench
                outcome = "not installed"
            except Exception as err:  # noqa: BLE001 - the row names what each client raised
                outcome = type(err).__name__
            wall = time.monotonic() - start
            held = "" if outcome == "not installed" else wall <= DEADLINE_S + 0.5
            rows.append({"client": name, "trickled": part, "deadline_s": DEADLINE_S, "wall_s": round(wall, 2),
                         "outcome": outcome, "holds the deadline": held})
        server.close()
    return rows
