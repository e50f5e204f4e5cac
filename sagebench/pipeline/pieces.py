"""A run's collider pieces as executor tasks: each scene's export lists the concave pieces it lacks in the
cache (a plan task), each piece runs as its own task (its methods, time budget and cache entry as in
export-usd), and the scene's export task then finds every piece cached. So the pieces of all scenes form one
pool of work for the run's workers or its Ray cluster, instead of one scene's pieces per export task.
"""

from __future__ import annotations

import os
import socket
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from sagebench import ui
from sagebench.collider_export.pieces import Piece, piece_key
from sagebench.pipeline.tasks import STAGES, Task, stage_key, up_to_date

EXPORT = "export_usd"


@dataclass(frozen=True)
class PieceTask:
    """One concave piece of one scene's export, everything a worker needs (picklable)."""

    scene_id: str
    key: str  # the piece's cache key
    piece: Piece
    band: tuple[float, float]  # the agent's band the piece is judged in (world z, m)
    colliders: dict[str, Any]  # the ColliderSettings of the piece's pass as JSON data (quality runs two passes)
    cache_dir: Path | None = None  # the run's CoACD cache

    @property
    def cost(self) -> int:
        """Expected cost, to start the biggest first: the piece's face count."""
        return len(self.piece.faces)


@dataclass(frozen=True)
class PieceOutcome:
    key: str
    name: str
    method: str  # what made the parts; "" when the task failed (the export then decomposes the piece itself)
    seconds: float
    worker: str  # host:pid of the process that ran it
    warnings: tuple[str, ...] = ()
    error: str = ""


def plan_export(task: Task) -> tuple[PieceTask, ...]:
    """The pieces of TASK's export (an export_usd Task) missing from the cache, one per cache key; none when the
    stage is up to date, or when the scene cannot be read (its export task then reports why). Never raises."""
    from sagebench.settings.export_usd import ExportConfig
    from sagebench.stages.export_usd import part_cache, scene_pieces

    try:
        with ui.collect_warnings():
            if up_to_date(task, stage_key(task, STAGES[EXPORT].inputs(task))):
                return ()
            config = ExportConfig.model_validate(task.settings)
            cache = part_cache(task.cache_dir)
            jobs, band = scene_pieces(task.run_dir, task.scene_id, config, cache)
            out: dict[str, PieceTask] = {}
            for piece, colliders in jobs:
                key = piece_key(piece, colliders, band)
                if key not in out and not cache.has(key):
                    out[key] = PieceTask(task.scene_id, key, piece, band, colliders.model_dump(mode="json"),
                                         task.cache_dir)
            return tuple(out.values())
    except Exception:  # noqa: BLE001 - the export task meets the same error and reports it as the scene's failure
        return ()


def run_piece(task: PieceTask) -> PieceOutcome:
    """Decompose one piece into the cache; never raises (a failed piece is decomposed again by its export)."""
    from sagebench.settings.export_usd import ColliderSettings
    from sagebench.stages.export_usd import decompose_piece

    start = time.perf_counter()
    worker = f"{socket.gethostname()}:{os.getpid()}"
    with ui.collect_warnings() as found:
        try:
            result = decompose_piece(task.piece, ColliderSettings.model_validate(task.colliders), task.band,
                                     task.cache_dir)
            method, error = result.method, ""
        except Exception as err:  # noqa: BLE001
            method, error = "", f"{type(err).__name__}: {err}"
    return PieceOutcome(task.key, task.piece.name, method, time.perf_counter() - start, worker, tuple(found), error)
