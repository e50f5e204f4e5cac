"""CoACD's settings and runner, and the content-addressed cache of every piece's collider parts.

The cache key is sha256 of (vertex and face bytes, coacd version, the collider settings), so an asset that
appears in many scenes (or many times in one) is decomposed once per machine.
"""

from __future__ import annotations

import hashlib
import io
import json
from dataclasses import dataclass
from importlib.metadata import version
from pathlib import Path
from typing import Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from sagebench import ui
from sagebench.collider_export.convex import ConvexPart
from sagebench.fileio import write_bytes

CACHE_SUBDIR = "colliders-v3"  # bumped whenever a method's parts change for the same settings (v3: voxel hulls)


class CoacdParams(BaseModel):
    """The CoACD settings sagebench exposes; every one of them is part of the cache key.

    The search settings are cut from CoACD's own defaults (resolution 2000, 150 MCTS iterations of depth 3
    over 20 nodes): on the 19 pieces of the real-furniture bench scene whose hull misses the agent band, this
    took 44 CPU s against 157 s with 3 pieces over 40 s, for the same band errors (16 against 15 of them
    within 2 cm) and median surface distance (0.9 against 1.1 cm); on 15 pieces drawn from the rest, 12
    against 29 CPU s, same band errors and surface distances.
    """

    model_config = ConfigDict(extra="forbid", frozen=True)

    threshold: float = Field(default=0.05, gt=0, le=1, description="Concavity threshold; smaller gives more, tighter parts.")
    max_convex_hull: int = Field(default=-1, ge=-1, description="Cap on parts per piece; -1 for no cap.")
    preprocess_mode: Literal["auto", "on", "off"] = Field(
        default="auto", description="Manifold preprocessing; 'off' is much faster on clean watertight meshes."
    )
    preprocess_resolution: int = Field(default=50, gt=0)
    resolution: int = Field(default=1000, gt=0, description="Sampling resolution of the concavity metric.")
    mcts_iterations: int = Field(default=60, gt=0, description="Monte Carlo tree search iterations per cut.")
    mcts_max_depth: int = Field(default=2, gt=0, description="Cuts the tree search looks ahead.")
    mcts_nodes: int = Field(default=10, gt=0, description="Candidate cutting planes per tree node.")
    seed: int = Field(default=0, ge=0)


@dataclass(frozen=True)
class PieceResult:
    """The convex parts of one concave piece, the method that made them and how well they fit the agent band."""

    parts: list[ConvexPart]
    method: str  # hull, voxel or coacd
    key: str
    band_error_cm: float  # the worse of the band over/under figures against the piece
    cached: bool = False  # read back from the cache in this run


def coacd_version() -> str:
    return version("coacd")


def cache_key(vertices: np.ndarray, faces: np.ndarray, settings: BaseModel, **extra: object) -> str:
    """sha256 hex of the piece's float64 vertices [V, 3], int64 faces [F, 3], coacd version, settings and extras."""
    h = hashlib.sha256()
    v = np.ascontiguousarray(vertices, dtype="<f8")
    f = np.ascontiguousarray(faces, dtype="<i8")
    h.update(f"{v.shape}{f.shape}".encode())
    h.update(v.tobytes())
    h.update(f.tobytes())
    h.update(json.dumps({"coacd": coacd_version(), **settings.model_dump(mode="json"), **extra}, sort_keys=True,
                        default=str).encode())
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
        mcts_max_depth=params.mcts_max_depth,
        mcts_nodes=params.mcts_nodes,
        seed=params.seed,
    )
    parts = [(np.asarray(v, dtype=np.float64), np.asarray(f, dtype=np.int64)) for v, f in out if len(f)]
    if not parts:
        raise RuntimeError("CoACD returned no parts")
    return parts


def _encode(result: PieceResult) -> bytes:
    arrays = {"meta": np.frombuffer(json.dumps({"method": result.method, "band_error_cm": result.band_error_cm}).encode(),
                                    dtype=np.uint8)}
    for i, p in enumerate(result.parts):
        arrays[f"v{i:04d}"] = p.vertices
        arrays[f"f{i:04d}"] = p.faces
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    return buf.getvalue()


def _decode(data: bytes, key: str) -> PieceResult:
    with np.load(io.BytesIO(data)) as z:
        meta = json.loads(z["meta"].tobytes())
        n = (len(z.files) - 1) // 2
        parts = [ConvexPart(z[f"v{i:04d}"], z[f"f{i:04d}"]) for i in range(n)]
    return PieceResult(parts, meta["method"], key, float(meta["band_error_cm"]), cached=True)


class PartCache:
    """Piece results on disk: CACHE_DIR/colliders-v3/<key[:2]>/<key>.npz, each written atomically when its
    piece is done (so an interrupted run keeps what it finished)."""

    def __init__(self, root: Path | None):
        self.root = None if root is None else Path(root) / CACHE_SUBDIR

    def _path(self, key: str) -> Path | None:
        return None if self.root is None else self.root / key[:2] / f"{key}.npz"

    def get(self, key: str) -> PieceResult | None:
        path = self._path(key)
        if path is None or not path.is_file():
            return None
        try:
            return _decode(path.read_bytes(), key)
        except (OSError, ValueError, KeyError):
            ui.warn(f"ignoring unreadable cache entry {path}")
            return None

    def has(self, key: str) -> bool:
        """Whether a result for `key` is on disk (without reading it)."""
        path = self._path(key)
        return path is not None and path.is_file()

    def put(self, result: PieceResult) -> None:
        path = self._path(result.key)
        if path is not None:
            write_bytes(path, _encode(result))
