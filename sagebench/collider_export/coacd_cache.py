"""CoACD's settings and runner, and the content-addressed cache of every piece's collider parts and of every
mesh's split into exact parts and concave pieces.

A piece's key is sha256 of (vertex and face bytes, coacd version, the collider settings), so an asset that
appears in many scenes (or many times in one) is decomposed once per machine. A mesh's split is cached
too: `sagebench run` splits each scene's meshes in its plan task and again in its export, and a warm
export splits them again (4 CPU-s of the bench scene's 463 k faces each time).
"""

from __future__ import annotations

import ctypes
import hashlib
import io
import json
from collections.abc import Mapping
from dataclasses import dataclass
from importlib.metadata import version
from pathlib import Path

import numpy as np
from pydantic import BaseModel

from sagebench import ui
from sagebench.collider_export.convex import ConvexPart, ConvexSplit
from sagebench.fileio import write_bytes
from sagebench.settings.export_usd import CoacdParams

CACHE_SUBDIR = "colliders-v4"  # bumped whenever a method's parts change for the same settings (v4: one-thread CoACD)
SPLIT_VERSION = 2  # bumped whenever convex.split_convex splits the same mesh differently


@dataclass(frozen=True)
class PieceResult:
    """The convex parts of one concave piece, the method that made them and how well they fit the agent band."""

    parts: list[ConvexPart]
    method: str  # hull, voxel, coacd or coacd_fine (methods.Method)
    key: str
    band_error_cm: float  # the worse of the band over/under figures against the piece
    cached: bool = False  # read back from the cache in this run


def coacd_version() -> str:
    return version("coacd")


def cache_key(vertices: np.ndarray, faces: np.ndarray, settings: BaseModel, *, exclude: frozenset[str] = frozenset(),
              **extra: object) -> str:
    """sha256 hex of the piece's float64 vertices [V, 3], int64 faces [F, 3], coacd version, settings (less the
    fields in `exclude`) and extras."""
    h = hashlib.sha256()
    v = np.ascontiguousarray(vertices, dtype="<f8")
    f = np.ascontiguousarray(faces, dtype="<i8")
    h.update(f"{v.shape}{f.shape}".encode())
    h.update(v.tobytes())
    h.update(f.tobytes())
    fields = settings.model_dump(mode="json", exclude=set(exclude))
    h.update(json.dumps({"coacd": coacd_version(), **fields, **extra}, sort_keys=True, default=str).encode())
    return h.hexdigest()


def run_coacd(vertices: np.ndarray, faces: np.ndarray, params: CoacdParams,
              threads: int | None = None) -> list[tuple[np.ndarray, np.ndarray]]:
    """CoACD on one piece: a list of (vertices [V, 3] float64, faces [F, 3] int64) hulls; raises on failure.
    `threads`: OpenMP threads of its parallel loop (None: OpenMP's default); 1 gives the same parts whatever
    the machine's load, since the loop collects parts in the order its threads finish them."""
    import coacd

    coacd.set_log_level("error")
    if threads is not None:
        _openmp(coacd).omp_set_num_threads(threads)
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


def _openmp(coacd_module) -> ctypes.CDLL:
    """The OpenMP runtime CoACD's wheel ships beside it (coacd.libs/libgomp-*.so), the one its library loaded."""
    libs = sorted((Path(coacd_module.__file__).parent.parent / "coacd.libs").glob("libgomp*.so*"))
    if not libs:
        raise RuntimeError("CoACD's OpenMP runtime (coacd.libs/libgomp*.so) was not found")
    return ctypes.CDLL(str(libs[0]))


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


def split_key(vertices: np.ndarray, faces: np.ndarray, tolerance: float) -> str:
    """sha256 hex of a mesh's split_convex input: vertices [V, 3], faces [F, 3] and the convex tolerance."""
    return cache_key(vertices, faces, _SplitSettings(tolerance=tolerance), split_version=SPLIT_VERSION)


class _SplitSettings(BaseModel):
    tolerance: float


def _pack(meshes: list[tuple[np.ndarray, np.ndarray]], prefix: str) -> dict[str, np.ndarray]:
    """Many (vertices [V, 3], faces [F, 3]) as four arrays: both concatenated, and the counts to cut them at."""
    return {f"{prefix}_v": np.concatenate([v for v, _ in meshes]) if meshes else np.zeros((0, 3)),
            f"{prefix}_f": np.concatenate([f for _, f in meshes]) if meshes else np.zeros((0, 3), dtype=np.int64),
            f"{prefix}_nv": np.array([len(v) for v, _ in meshes], dtype=np.int64),
            f"{prefix}_nf": np.array([len(f) for _, f in meshes], dtype=np.int64)}


def _unpack(z: Mapping[str, np.ndarray], prefix: str) -> list[tuple[np.ndarray, np.ndarray]]:
    cut = lambda a, n: np.split(a, np.cumsum(n)[:-1]) if len(n) else []  # noqa: E731
    return list(zip(cut(z[f"{prefix}_v"], z[f"{prefix}_nv"]), cut(z[f"{prefix}_f"], z[f"{prefix}_nf"])))


def _encode_split(split: ConvexSplit) -> bytes:
    buf = io.BytesIO()
    np.savez(buf, **_pack([(p.vertices, p.faces) for p in split.parts], "parts"), **_pack(split.concave, "concave"))
    return buf.getvalue()


def _decode_split(data: bytes) -> ConvexSplit:
    with np.load(io.BytesIO(data)) as z:
        arrays = {k: z[k] for k in z.files}
    return ConvexSplit([ConvexPart(v, f) for v, f in _unpack(arrays, "parts")], _unpack(arrays, "concave"))


class PartCache:
    """Piece results on disk: CACHE_DIR/colliders-v4/<key[:2]>/<key>.npz, each written atomically when its
    piece is done (so an interrupted run keeps what it finished); mesh splits in CACHE_DIR/splits/."""

    def __init__(self, root: Path | None):
        self.root = None if root is None else Path(root) / CACHE_SUBDIR
        self.splits = None if root is None else Path(root) / "splits"

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

    def get_split(self, key: str) -> ConvexSplit | None:
        path = None if self.splits is None else self.splits / key[:2] / f"{key}.npz"
        if path is None or not path.is_file():
            return None
        try:
            return _decode_split(path.read_bytes())
        except (OSError, ValueError, KeyError):
            ui.warn(f"ignoring unreadable cache entry {path}")
            return None

    def put_split(self, key: str, split: ConvexSplit) -> None:
        if self.splits is not None:
            write_bytes(self.splits / key[:2] / f"{key}.npz", _encode_split(split))
