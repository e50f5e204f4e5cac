"""Collider work spread over processes: the fork server they start from, and one function over many inputs.

A piece's process (collider_export/pieces.py) is forked from a server that has already imported what the
workers need, so that costs a piece nothing: OpenCV (the band measure's rasteriser; 43 ms in every piece's
process before, 9 CPU-s over the bench scene's 210 pieces), CoACD and pymeshfix (imported where used by
methods.py). Splitting a scene's meshes and measuring its colliders are independent per mesh; they took
8 and 7 CPU-s one after the other on the bench scene while the second core idled.
"""

from __future__ import annotations

import multiprocessing
import signal
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor
from typing import Any, TypeVar

from sagebench import ui

R = TypeVar("R")

WORKER_PRELOAD = ("sagebench.collider_export.pieces", "cv2", "coacd", "pymeshfix")


def worker_context() -> multiprocessing.context.BaseContext:
    """The fork-server context of collider workers (the server starts once per process, preloaded).

    The server starts with SIGINT ignored: Ctrl-C reaches every process of the terminal's group, and one arriving
    while it imports its preload printed a KeyboardInterrupt traceback of its own. Its children inherit that; a
    piece worker takes SIGINT's default back (pieces._work), so Ctrl-C ends it silently."""
    import threading
    from multiprocessing import forkserver

    ctx = multiprocessing.get_context("forkserver")
    ctx.set_forkserver_preload(list(WORKER_PRELOAD))
    if threading.current_thread() is threading.main_thread():  # signal handlers can be set there only
        previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
        try:
            forkserver.ensure_running()
        finally:
            signal.signal(signal.SIGINT, previous)
    return ctx


def map_processes(fn: Callable[..., R], args: Sequence[tuple[Any, ...]], *, workers: int,
                  sizes: Sequence[float] | None = None) -> list[R]:
    """[fn(*a) for a in args], on up to `workers` processes when there are several inputs, started largest
    `sizes` first so that a big one does not finish last; in this process when workers <= 1."""
    if workers <= 1 or len(args) <= 1:
        return [fn(*a) for a in args]
    order = sorted(range(len(args)), key=lambda i: -sizes[i]) if sizes is not None else range(len(args))
    out: list[Any] = [None] * len(args)
    with ProcessPoolExecutor(max_workers=min(workers, len(args)), mp_context=worker_context(),
                             initializer=ui.adopt, initargs=(ui.worker_settings(),)) as pool:
        futures = {pool.submit(fn, *args[i]): i for i in order}
        for future, i in futures.items():
            out[i] = future.result()
    return out
