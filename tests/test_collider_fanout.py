"""Collider workers: a fork server that has already imported what they need; a function over many inputs."""

from __future__ import annotations

import os
import sys

from sagebench.collider_export.fanout import WORKER_PRELOAD, map_processes, worker_context


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


def _digits(tens: int, ones: int) -> tuple[int, int]:
    return tens * 10 + ones, os.getpid()


def test_map_processes_returns_results_in_input_order_from_other_processes():
    args = [(i, i % 3) for i in range(7)]
    out = map_processes(_digits, args, workers=2, sizes=[i % 4 for i in range(7)])  # started in another order
    assert [v for v, _ in out] == [10 * i + i % 3 for i in range(7)]
    assert os.getpid() not in {pid for _, pid in out}
    assert {pid for _, pid in map_processes(_digits, args, workers=1)} == {os.getpid()}
