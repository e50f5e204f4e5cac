"""Which of a run's tasks goes to the executor next: each stage of each scene once the stages it comes after
succeeded, and the run's collider pieces as one pool, biggest first.

A scene's export first gets a plan task (pipeline/pieces.py) listing the pieces it lacks in the cache; those
join the run's queue of pieces, at most `executor.capacity` in flight so a big piece planned later still
starts before smaller ones queued earlier; the export task is submitted once its last piece is done (it then
reads every piece from the cache). A piece shared by several scenes runs once.
"""

from __future__ import annotations

import heapq
import time
from collections.abc import Iterator
from pathlib import Path

from sagebench import ui
from sagebench.collider_export.pieces import PieceProgress
from sagebench.pipeline.executors import Executor
from sagebench.pipeline.pieces import EXPORT, PieceOutcome, PieceTask, plan_export, run_piece
from sagebench.pipeline.tasks import STAGES, Outcome, Task, run_task


class RunScheduler:
    def __init__(self, executor: Executor, sources: dict[str, Path], run_dir: Path, settings: dict,
                 cache_dir: Path | None):
        self.executor, self.sources, self.run_dir = executor, sources, run_dir
        self.settings, self.cache_dir = settings, cache_dir
        self.done: dict[tuple[str, str], Outcome] = {}
        self.submitted: set[tuple[str, str]] = set()
        self.handles: dict[int, tuple[str, object]] = {}  # id(handle) -> ("stage", (sid, stage)) | ("plan", sid)
        self.order: list[object] = []  #                                  | ("piece", PieceTask)
        self.planned: dict[str, set[str] | None] = {}  # scene id -> keys of the pieces its export waits for
        #                                                (None while its plan task runs)
        self.waiters: dict[str, set[str]] = {}  # piece key -> scene ids waiting for it (queued or in flight)
        self.queue: list[tuple[int, int, PieceTask]] = []  # (-cost, arrival, task): a heap, biggest first
        self.started: dict[str, tuple[str, float]] = {}  # piece key in flight -> (name, when submitted)
        self.pieces: list[PieceOutcome] = []
        self.progress = PieceProgress()

    def outcomes(self) -> Iterator[Outcome]:
        """Run every task; yield each stage outcome as it ends (piece outcomes are kept in `pieces`)."""
        for sid in sorted(self.sources):
            self._submit_ready(sid)
        while self.order:
            for handle, result in self.executor.wait_any(self.order):
                self.order.remove(handle)
                kind, what = self.handles.pop(id(handle))
                if kind == "stage":
                    self.done[what] = result
                    yield result
                    if result.status != "failed":
                        self._submit_ready(what[0])
                elif kind == "plan":
                    self._planned(what, result)
                else:
                    self._piece_done(what, result)
            self.progress.tick({name: time.monotonic() - t for name, t in self.started.values()})
        if self.progress.total:
            self.progress.finish()

    def _submit(self, fn, arg, what: tuple[str, object], cpus: int = 1) -> None:
        handle = self.executor.submit(fn, arg, cpus=cpus)
        self.handles[id(handle)] = what
        self.order.append(handle)

    def _submit_ready(self, sid: str) -> None:
        for name, stage in STAGES.items():
            key = (sid, name)
            if key in self.done or key in self.submitted:
                continue
            if not all((sid, a) in self.done and self.done[(sid, a)].status != "failed" for a in stage.after):
                continue
            task = Task(name, sid, self.sources[sid], self.run_dir, self.settings[name], self.cache_dir)
            if name == EXPORT:
                if sid not in self.planned:
                    self.planned[sid] = None
                    self._submit(plan_export, task, ("plan", sid))
                if self.planned[sid] is None or self.planned[sid]:
                    continue  # its plan or pieces still to come
            self.submitted.add(key)
            self._submit(run_task, task, ("stage", key), cpus=stage.cpus(task))

    def _planned(self, sid: str, pieces: tuple[PieceTask, ...]) -> None:
        self.planned[sid] = set()
        for piece in pieces:
            self.planned[sid].add(piece.key)
            if piece.key not in self.waiters:
                self.waiters[piece.key] = set()
                heapq.heappush(self.queue, (-piece.cost, self.progress.total, piece))
                self.progress.total += 1
            self.waiters[piece.key].add(sid)
        self._dispatch()
        self._submit_ready(sid)

    def _dispatch(self) -> None:
        """Keep the executor's capacity busy with pieces, biggest first."""
        while self.queue and len(self.started) < self.executor.capacity:
            _, _, piece = heapq.heappop(self.queue)
            self.started[piece.key] = (piece.piece.name, time.monotonic())
            self._submit(run_piece, piece, ("piece", piece))

    def _piece_done(self, piece: PieceTask, outcome: PieceOutcome) -> None:
        del self.started[piece.key]
        self.pieces.append(outcome)
        self.progress.done(outcome.name, outcome.seconds)
        for message in outcome.warnings:
            ui.warn(f"{piece.scene_id} {EXPORT}: {message}")
        if outcome.error:
            ui.warn(f"{piece.scene_id} {EXPORT}: {outcome.name}: {outcome.error}; its export decomposes it again")
        for sid in sorted(self.waiters.pop(piece.key)):
            self.planned[sid].discard(piece.key)
            self._submit_ready(sid)
        self._dispatch()
