"""One request over SAGE-Bench's socket protocol: connect, send a frame (8-byte big-endian length + payload), read
the reply framed the same way, close. One deadline for all of it; a refused connection (nothing sent) is retried
with backoff; a reply longer than `max_bytes` is refused before it is read."""

from __future__ import annotations

import socket
import time


class SocketFailure(Exception):
    """A request that got no whole reply; the message says why (one line)."""


def exchange(host: str, port: int, frame: bytes, *, timeout: float, retries: int = 3, backoff: float = 0.1,
             max_bytes: int) -> bytes:
    """The reply's payload to `frame`, sent to host:port (module docstring)."""
    deadline = time.monotonic() + timeout
    for n in range(retries + 1):
        try:
            sock = socket.create_connection((host, port), timeout=_left(deadline, timeout))
            break
        except ConnectionError as err:
            if n == retries or time.monotonic() + backoff * 2**n >= deadline:
                raise SocketFailure(f"connection error: {type(err).__name__}: {err}") from None
            time.sleep(backoff * 2**n)
        except OSError as err:
            raise SocketFailure(_why(err, timeout)) from None
    with sock:
        try:
            sock.sendall(frame)
            size = int.from_bytes(_read(sock, 8, deadline, timeout, "length header"), "big")
            if size > max_bytes:
                raise SocketFailure(f"the reply is larger than {max_bytes:,} bytes ({size:,} announced)")
            return _read(sock, size, deadline, timeout, "reply")
        except OSError as err:
            raise SocketFailure(_why(err, timeout)) from None


def _read(sock: socket.socket, size: int, deadline: float, timeout: float, what: str) -> bytes:
    data = bytearray()
    while len(data) < size:
        sock.settimeout(_left(deadline, timeout))
        chunk = sock.recv(min(1 << 16, size - len(data)))
        if not chunk:
            raise SocketFailure(f"the server closed the connection after {len(data)} of the {size} bytes of its {what}")
        data += chunk
    return bytes(data)


def _left(deadline: float, timeout: float) -> float:
    left = deadline - time.monotonic()
    if left <= 0:
        raise SocketFailure(f"no reply within {timeout:g} s")
    return left


def _why(err: OSError, timeout: float) -> str:
    if isinstance(err, TimeoutError):
        return f"no reply within {timeout:g} s"
    return f"connection error: {type(err).__name__}: {err}".rstrip(": ")
