"""Colliders for many concave pieces: each in a worker process that can be killed, biggest first, cached as done.

A piece runs its methods (methods.ladder) in one process that reports each result as it has it; which
result it keeps depends on the results alone, so the parts are the same however busy the machine is. A method
still running after the safety limit (`piece_limit_s`) stops the whole batch with a ColliderError naming the
piece, the method and the limit: the clock never picks a method. A method that fails or crashes hands over to
the next one in a fresh process (keeping what it already had). Ctrl-C and the limit kill the workers at
once; every finished piece is already in the cache, so a rerun starts where this one stopped. Progress
(pieces done / total, the slowest piece, time left) goes to stderr every few seconds, terminal or not.
"""

from __future__ import annotations

import multiprocessing
import os
import signal
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from multiprocessing.connection import Connection, wait

import numpy as np

from sagebench import ui
from sagebench.collider_export.coacd_cache import PartCache, PieceResult, cache_key
from sagebench.collider_export.convex import ConvexPart, hull_part
from sagebench.collider_export.fanout import worker_context
from sagebench.collider_export.methods import UNSHAPING, Method, band_error_cm, good_enough, run_method
from sagebench.errors import ColliderError
from sagebench.settings.export_usd import ColliderSettings


@dataclass(frozen=True)
class Piece:
    """One job: a name for messages, the mesh [V, 3] / [F, 3], and the methods to try in order."""

    name: str
    vertices: np.ndarray
    faces: np.ndarray
    methods: tuple[Method, ...]


@dataclass
class _Run:
    """A piece being worked on: its process, the method running now and what the earlier ones gave."""

    index: int
    key: str
    process: multiprocessing.process.BaseProcess | None
    methods: list[Method]  # still to start, in order (the first is running)
    started: float  # when the running method started (time.monotonic)
    piece_started: float
    results: list[tuple[Method, list[ConvexPart], float]] = field(default_factory=list)  # (method, parts, band cm)
    accepted: bool = False


def piece_key(piece: Piece, settings: ColliderSettings, band: tuple[float, float]) -> str:
    """The piece's cache key: its mesh, methods, the agent band (z) and the settings that shape parts."""
    return cache_key(piece.vertices, piece.faces, settings, exclude=UNSHAPING, methods=list(piece.methods),
                     band=list(band))


def decompose_pieces(
    pieces: Sequence[Piece],
    settings: ColliderSettings,
    *,
    cache: PartCache,
    workers: int = 1,
    band: tuple[float, float],
    progress: bool = True,
) -> list[PieceResult]:
    """A result per piece, in input order; equal pieces run once, cached ones are read back. `band` is the agent's
    (bottom, top) as z in the pieces' frame, m. `progress` False leaves the progress lines to the caller (a run
    that hands out pieces one by one counts them itself)."""
    keys = [piece_key(p, settings, band) for p in pieces]
    done: dict[str, PieceResult] = {}
    todo: dict[str, int] = {}
    for i, key in enumerate(keys):
        if key in done or key in todo:
            continue
        hit = cache.get(key)
        if hit is not None:
            done[key] = hit
        else:
            todo[key] = i
    order = sorted(todo.values(), key=lambda i: -len(pieces[i].faces))  # the biggest set the pace: start them first
    if order:
        _Scheduler(pieces, keys, settings, cache, workers, band, progress).run(order, done)
    return [done[k] for k in keys]


class _Scheduler:
    def __init__(self, pieces, keys, settings: ColliderSettings, cache: PartCache, workers: int,
                 band: tuple[float, float], progress: bool):
        self.pieces, self.keys, self.settings, self.cache = pieces, keys, settings, cache
        self.workers, self.band = max(1, workers), band
        self.ctx = worker_context()
        self.running: dict[Connection, _Run] = {}
        self.progress = PieceProgress(quiet=not progress)

    def run(self, todo: list[int], done: dict[str, PieceResult]) -> None:
        queue = list(todo)
        self.progress.total = len(queue)
        try:
            while queue or self.running:
                while queue and len(self.running) < self.workers:
                    i = queue.pop(0)
                    now = time.monotonic()
                    self._start(_Run(i, self.keys[i], None, list(self.pieces[i].methods), now, now))
                ready = wait(list(self.running), timeout=self._next_deadline())
                for conn in ready:
                    self._receive(conn, done)
                for run in self.running.values():
                    if time.monotonic() - run.started > self.settings.piece_limit_s:
                        self._over_limit(run)
                self.progress.tick(self._elapsed())
        except BaseException:
            for conn, run in self.running.items():
                run.process.kill()
            for conn, run in self.running.items():
                run.process.join()
                conn.close()
            self.running.clear()
            raise
        self.progress.finish()

    def _start(self, run: _Run) -> None:
        piece = self.pieces[run.index]
        parent, child = self.ctx.Pipe(duplex=False)
        run.process = self.ctx.Process(target=_work, args=(child, piece.vertices, piece.faces, tuple(run.methods),
                                                           self.settings, self.band), daemon=True)
        run.process.start()
        child.close()
        run.started = time.monotonic()
        self.running[parent] = run

    def _next_deadline(self) -> float:
        now = time.monotonic()
        left = [self.settings.piece_limit_s - (now - r.started) for r in self.running.values()]
        return float(np.clip(min(left, default=1.0), 0.05, 1.0))

    def _elapsed(self) -> dict[str, float]:
        now = time.monotonic()
        return {self.pieces[r.index].name: now - r.piece_started for r in self.running.values()}

    def _receive(self, conn: Connection, done: dict[str, PieceResult]) -> None:
        run = self.running[conn]
        while True:
            try:
                if not conn.poll():
                    return
                msg = conn.recv()
            except (EOFError, OSError):  # the worker died (a crash inside a native library)
                method = run.methods[0] if run.methods else "?"
                ui.warn(f"{self.pieces[run.index].name}: {method} crashed; trying the next method")
                self._retire(conn)
                self._continue(run, done, skip=1)
                return
            if msg[0] == "start":
                run.started = time.monotonic()
            elif msg[0] == "result":
                _, method, parts, error_cm, failure = msg
                run.methods.pop(0)
                if failure is not None:
                    ui.warn(f"{self.pieces[run.index].name}: {method} failed ({failure}); trying the next method")
                else:
                    run.results.append((method, parts, error_cm))
                    run.accepted = good_enough(error_cm, self.settings)
            elif msg[0] == "end":
                self._retire(conn)
                self._finish(run, done)
                return

    def _over_limit(self, run: _Run) -> None:
        method = run.methods[0] if run.methods else "its band measure"
        raise ColliderError(f"{self.pieces[run.index].name}: {method} still running after "
                            f"{self.settings.piece_limit_s:g} s, the safety limit (--piece-limit); nothing was "
                            "written: raise the limit, or choose a --colliders mode without this method")

    def _retire(self, conn: Connection) -> None:
        run = self.running.pop(conn)
        if run.process.is_alive():
            run.process.kill()
        run.process.join()
        conn.close()

    def _continue(self, run: _Run, done: dict[str, PieceResult], *, skip: int) -> None:
        """Drop the method that did not finish; start the rest of the ladder, or finish with what there is."""
        del run.methods[:skip]
        if run.methods and not run.accepted:
            self._start(run)
        else:
            self._finish(run, done)

    def _finish(self, run: _Run, done: dict[str, PieceResult]) -> None:
        piece = self.pieces[run.index]
        if run.accepted:
            method, parts, error = run.results[-1]
        elif run.results:
            method, parts, error = min(run.results, key=lambda r: (r[2], len(r[1])))
        else:  # every method failed: the hull always exists
            parts = [hull_part(piece.vertices)]
            method, error = "hull", band_error_cm(piece.vertices, piece.faces, parts, self.band)
        result = PieceResult(parts, method, run.key, error)
        self.cache.put(result)
        done[run.key] = result
        self.progress.done(piece.name, time.monotonic() - run.piece_started)


def _work(conn: Connection, vertices: np.ndarray, faces: np.ndarray, methods: tuple[Method, ...],
          settings: ColliderSettings, band: tuple[float, float]) -> None:
    """Worker body: run the methods in order, report each (start, result), stop at the first good enough.
    Native libraries' own prints (pymeshfix's "could not fix everything") are silenced: results and failures
    reach the parent through `conn`."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)  # the fork server ignores it (fanout.worker_context)
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, 1)
    os.dup2(devnull, 2)
    for method in methods:
        conn.send(("start", method))
        try:
            parts = run_method(method, vertices, faces, settings, band)
        except Exception as err:  # CoACD and the repair raise many kinds; the next method handles all of them
            conn.send(("result", method, None, float("inf"), str(err) or type(err).__name__))
            continue
        error = band_error_cm(vertices, faces, parts, band)
        conn.send(("result", method, parts, error, None))
        if good_enough(error, settings):
            break
    conn.send(("end",))
    conn.close()


class PieceProgress:
    """`colliders: 12/40 pieces, slowest sofa (concave piece 2) 31 s, about 40 s left` on stderr every few seconds."""

    def __init__(self, total: int = 0, *, quiet: bool = False):
        self.total, self.quiet = total, quiet
        self.finished: list[float] = []
        self.slowest: tuple[str, float] = ("", 0.0)
        self.start = time.monotonic()
        self.last = self.start

    def done(self, name: str, seconds: float) -> None:
        self.finished.append(seconds)
        if seconds >= self.slowest[1]:
            self.slowest = (name, seconds)

    def tick(self, running: dict[str, float]) -> None:
        now = time.monotonic()
        if not self.quiet and now - self.last >= ui.PROGRESS_EVERY_S:
            self.last = now
            ui.info(self.line(running))

    def finish(self) -> None:
        if not self.quiet:
            ui.info(self.line({}))

    def line(self, running: dict[str, float]) -> str:
        n = len(self.finished)
        slow = max([self.slowest, *running.items()], key=lambda kv: kv[1])
        text = f"colliders: {n}/{self.total} pieces in {time.monotonic() - self.start:.0f} s"
        if slow[0]:
            text += f", slowest {slow[0]} {slow[1]:.1f} s"
        if 0 < n < self.total:
            rate = (time.monotonic() - self.start) / n
            text += f", about {rate * (self.total - n):.0f} s left"
        return text
