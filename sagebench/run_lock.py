"""One `sagebench run` per run directory: an exclusive flock on RUN/.sagebench.lock.

The kernel drops a flock when its holder exits in any way (kill -9 included), so a crash never leaves a
stale lock to clear by hand. The file stays after the run: unlinking it would let a waiting process lock
an inode nobody else can see.
"""

from __future__ import annotations

import contextlib
import fcntl
import os
from collections.abc import Iterator
from pathlib import Path

from sagebench.errors import SagebenchError
from sagebench.run_layout import LOCK


class RunLockedError(SagebenchError):
    """Another process holds the run directory's lock."""


@contextlib.contextmanager
def run_lock(run_dir: Path) -> Iterator[Path]:
    """Hold RUN_DIR's lock for the body; RunLockedError (one line, naming the holder's pid) if it is held."""
    path = Path(run_dir) / LOCK
    fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o666)
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = os.pread(fd, 32, 0).decode("ascii", "replace").strip() or "unknown"
            raise RunLockedError(f"another `sagebench run` (pid {holder}) is writing this run directory; "
                                 "wait for it to end or set another `out`", path=run_dir) from None
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"{os.getpid()}\n".encode("ascii"), 0)
        yield path
    finally:
        os.close(fd)
