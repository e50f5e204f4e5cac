"""Fixtures built once per test run, not once per xdist worker.

`make test` runs two workers, and a session fixture is per process: each worker would build the demo apartment,
its run and the tiny run again. `built_once` builds into a folder that all workers of one run share
(pytest's basetemp's parent under xdist, basetemp itself without it), under an exclusive flock: the first worker
to ask builds, the others wait on the lock and reuse what it built. What it built is read-only for the tests, now
across processes: on leaving, each worker checks that no file or folder in it was added, removed or changed.
"""

from __future__ import annotations

import contextlib
import fcntl
import os
import pickle
import shutil
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TypeVar

T = TypeVar("T")


def shared_root(tmp_path_factory) -> Path:
    """The folder every worker of this test run sees: under xdist each worker's basetemp is RUN/popen-gwN."""
    base = tmp_path_factory.getbasetemp()
    return base.parent if os.environ.get("PYTEST_XDIST_WORKER") else base


def _tree(root: Path) -> dict[str, tuple[int, int, int]]:
    """Every path under ROOT -> (mode, size, mtime_ns): what a write, a removal or an addition would change."""
    out = {}
    for p in sorted(root.rglob("*")):
        st = p.lstat()
        out[p.relative_to(root).as_posix()] = (st.st_mode, st.st_size, st.st_mtime_ns)
    return out


@contextlib.contextmanager
def built_once(tmp_path_factory, name: str, build: Callable[[Path], T]) -> Iterator[T]:
    """`build(folder)` once per test run in a fresh shared FOLDER; yields what it returned (pickled for the other
    workers). Raises on exit if anything in FOLDER changed after the build."""
    root = shared_root(tmp_path_factory)
    folder, done = root / f"shared-{name}", root / f"shared-{name}.pickle"
    with open(root / f"shared-{name}.lock", "a") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # released when the file closes, or when this worker dies
        if not done.exists():
            shutil.rmtree(folder, ignore_errors=True)  # a build that failed in another worker
            folder.mkdir()
            value = build(folder)
            tmp = done.with_suffix(".tmp")
            tmp.write_bytes(pickle.dumps((value, _tree(folder))))
            tmp.rename(done)
    value, tree = pickle.loads(done.read_bytes())
    yield value
    now = _tree(folder)
    changed = sorted(k for k in tree.keys() | now.keys() if tree.get(k) != now.get(k))
    assert not changed, f"a test wrote into the shared fixture {name} ({folder}): {changed[:5]}; copy it first"
