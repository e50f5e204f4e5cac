"""The fork server every collider worker process starts from, preloaded with what the workers import.

A piece's process (collider_export/pieces.py) is forked from it, so what the fork server has imported costs
a piece nothing: OpenCV (the band measure's rasteriser; 43 ms in every piece's process before, 9 CPU-s over
the bench scene's 210 pieces), CoACD and pymeshfix (imported where used by methods.py).
"""

from __future__ import annotations

import multiprocessing

WORKER_PRELOAD = ("sagebench.collider_export.pieces", "cv2", "coacd", "pymeshfix")


def worker_context() -> multiprocessing.context.BaseContext:
    """The fork-server context of collider workers (the server starts once per process, preloaded)."""
    ctx = multiprocessing.get_context("forkserver")
    ctx.set_forkserver_preload(list(WORKER_PRELOAD))
    return ctx
