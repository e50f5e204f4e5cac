"""CoACD on concave pieces, cached by content hash, in parallel processes, with a convex-hull fallback.

The cache key is sha256 of (vertex and face bytes, coacd version, parameters), so an asset that
appears in many scenes (or many times in one) is decomposed once per machine.
"""

from __future__ import annotations

import hashlib
import io
import json
import multiprocessing
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from importlib.metadata import version
from pathlib import Path
from typing import Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from sagebench import ui
from sagebench.collider_export.convex import ConvexPart, hull_part
from sagebench.fileio import write_bytes

CACHE_SUBDIR = "coacd-v1"


class CoacdParams(BaseModel):
    """The CoACD settings sagebench exposes; every one of them is part of the cache key."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    threshold: float = Field(default=0.05, gt=0, le=1, description="Concavity threshold; smaller gives more, tighter parts.")
    max_convex_hull: int = Field(default=-1, ge=-1, description="Cap on parts per piece; -1 for no cap.")
    preprocess_mode: Literal["auto", "on", "off"] = Field(
        default="auto", description="Manifold preprocessing; 'off' is much faster on clean watertight meshes."
    )
    preprocess_resolution: int = Field(default=50, gt=0)
    resolution: int = Field(default=2000, gt=0, description="Sampling resolution of the concavity metric.")
    mcts_iterations: int = Field(default=150, gt=0)
    seed: int = Field(default=0, ge=0)


@dataclass(frozen=True)
class PieceResult:
    """The convex parts of one concave piece and how they were obtained."""

    parts: list[ConvexPart]
    source: Literal["coacd", "cache", "hull_fallback"]
    key: str


def coacd_version() -> str:
    return version("coacd")


def cache_key(vertices: np.ndarray, faces: np.ndarray, params: CoacdParams) -> str:
    """sha256 hex of the piece's float64 vertices [V, 3], int64 faces [F, 3], coacd version and params."""
    h = hashlib.sha256()
    v = np.ascontiguousarray(vertices, dtype="<f8")
    f = np.ascontiguousarray(faces, dtype="<i8")
    h.update(f"{v.shape}{f.shape}".encode())
    h.update(v.tobytes())
    h.update(f.tobytes())
    h.update(json.dumps({"coacd": coacd_version(), **params.model_dump()}, sort_keys=True).encode())
    return h.hexdigest()


def run_coacd(vertices: np.ndarray, faces: np.ndarray, params: CoacdParams) -> list[tuple[np.ndarray, np.ndarray]]:
    """CoACD on one piece: a list of (vertices [V, 3] float64, faces [F, 3] int64) hulls; raises on failure."""
    import coacd

    coacd.set_log_level("error")
    out = coacd.run_coacd(
        coacd.Mesh(np.asarray(vertices, dtype=np.float64), np.asarray(faces, dtype=np.int32)),
        threshold=params.threshold,
        max_convex_hull=params.max_convex_hull,
        preprocess_mode=params.preprocess_mode,
        preprocess_resolution=params.preprocess_resolution,
        resolution=params.resolution,
        mcts_iterations=params.mcts_iterations,
        seed=params.seed,
    )
    parts = [(np.asarray(v, dtype=np.float64), np.asarray(f, dtype=np.int64)) for v, f in out if len(f)]
    if not parts:
        raise RuntimeError("CoACD returned no parts")
    return parts


def _encode(parts: list[ConvexPart]) -> bytes:
    arrays = {}
    for i, p in enumerate(parts):
        arrays[f"v{i:04d}"] = p.vertices
        arrays[f"f{i:04d}"] = p.faces
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    return buf.getvalue()


def _decode(data: bytes) -> list[ConvexPart]:
    with np.load(io.BytesIO(data)) as z:
        n = len(z.files) // 2
        return [ConvexPart(z[f"v{i:04d}"], z[f"f{i:04d}"]) for i in range(n)]


class PartCache:
    """CoACD results on disk: CACHE_DIR/coacd-v1/<key[:2]>/<key>.npz, written atomically."""

    def __init__(self, root: Path | None):
        self.root = None if root is None else Path(root) / CACHE_SUBDIR

    def _path(self, key: str) -> Path | None:
        return None if self.root is None else self.root / key[:2] / f"{key}.npz"

    def get(self, key: str) -> list[ConvexPart] | None:
        path = self._path(key)
        if path is None or not path.is_file():
            return None
        try:
            return _decode(path.read_bytes())
        except (OSError, ValueError, KeyError):
            ui.warn(f"ignoring unreadable cache entry {path}")
            return None

    def put(self, key: str, parts: list[ConvexPart]) -> None:
        path = self._path(key)
        if path is not None:
            write_bytes(path, _encode(parts))


def _decompose(vertices: np.ndarray, faces: np.ndarray, params: CoacdParams) -> list[ConvexPart]:
    """Worker body: CoACD, then each returned hull normalised (outward winding, flat ones padded)."""
    return [hull_part(v) for v, _ in run_coacd(vertices, faces, params)]


def decompose_pieces(
    pieces: Sequence[tuple[str, np.ndarray, np.ndarray]],
    params: CoacdParams,
    *,
    cache: PartCache,
    workers: int = 1,
) -> list[PieceResult]:
    """Convex parts for each (name, vertices [V, 3], faces [F, 3]) piece, in input order.

    Cached pieces are read back; equal pieces run once; the rest run on `workers` processes (1: in
    this process). A piece CoACD fails on becomes its convex hull, with a warning naming it.
    """
    keys = [cache_key(v, f, params) for _, v, f in pieces]
    done: dict[str, PieceResult] = {}
    todo: dict[str, int] = {}
    for i, key in enumerate(keys):
        if key in done or key in todo:
            continue
        hit = cache.get(key)
        if hit is not None:
            done[key] = PieceResult(hit, "cache", key)
        else:
            todo[key] = i
    if todo:
        for key, i, parts, error in _run_all(pieces, todo, params, workers):
            name, v, _ = pieces[i]
            if error is None:
                cache.put(key, parts)
                done[key] = PieceResult(parts, "coacd", key)
            else:
                ui.warn(f"{name}: CoACD failed ({error}); using its convex hull as the collider")
                done[key] = PieceResult([hull_part(v)], "hull_fallback", key)
    return [done[k] for k in keys]


def _run_all(pieces, todo: dict[str, int], params: CoacdParams, workers: int):
    """Yield (key, index, parts, error text or None) for every piece to decompose."""
    items = list(todo.items())
    if workers <= 1 or len(items) == 1:
        for key, i in ui.track(items, "CoACD", total=len(items)):
            try:
                yield key, i, _decompose(pieces[i][1], pieces[i][2], params), None
            except Exception as err:  # CoACD raises many kinds; the fallback handles all of them
                yield key, i, [], str(err) or type(err).__name__
        return
    ctx = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(max_workers=min(workers, len(items)), mp_context=ctx) as pool:
        futures = [(key, i, pool.submit(_decompose, pieces[i][1], pieces[i][2], params)) for key, i in items]
        for key, i, fut in ui.track(futures, "CoACD", total=len(futures)):
            try:
                yield key, i, fut.result(), None
            except Exception as err:  # includes a worker that died (BrokenProcessPool)
                yield key, i, [], str(err) or type(err).__name__
