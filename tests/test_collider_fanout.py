"""Collider workers start from a fork server that has already imported what they need."""

from __future__ import annotations

import sys

from sagebench.collider_export.fanout import WORKER_PRELOAD, worker_context


def _report_modules(conn) -> None:
    conn.send(sorted(m for m in WORKER_PRELOAD if m in sys.modules))
    conn.close()


def test_a_worker_starts_with_the_preloaded_modules():
    ctx = worker_context()
    parent, child = ctx.Pipe(duplex=False)
    process = ctx.Process(target=_report_modules, args=(child,))
    process.start()
    child.close()
    assert parent.recv() == sorted(WORKER_PRELOAD)  # this module imports none of them itself
    process.join()
    assert "cv2" in WORKER_PRELOAD  # the band measure every piece runs draws with OpenCV
