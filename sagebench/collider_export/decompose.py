"""Convex collider parts for a set of meshes: exact convex pieces directly, concave pieces through CoACD."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from sagebench.collider_export.coacd_cache import CoacdParams, PartCache, PieceResult, decompose_pieces
from sagebench.collider_export.convex import ConvexPart, split_convex


@dataclass(frozen=True)
class MeshColliders:
    """All convex parts of one mesh (in the mesh file's frame) and where they came from."""

    parts: list[ConvexPart]
    exact_parts: int  # parts that are convex pieces of the mesh itself
    pieces: list[PieceResult]  # one per concave piece, in mesh order


def decompose_meshes(
    meshes: Mapping[str, tuple[np.ndarray, np.ndarray]],
    params: CoacdParams,
    *,
    cache: PartCache,
    workers: int = 1,
    convex_tolerance: float = 0.002,
) -> dict[str, MeshColliders]:
    """Parts for each named mesh (vertices [V, 3], faces [F, 3]); all concave pieces share one CoACD batch."""
    splits = {name: split_convex(v, f, tolerance=convex_tolerance) for name, (v, f) in meshes.items()}
    jobs = [
        (f"{name} (concave piece {k})", pv, pf)
        for name, split in splits.items()
        for k, (pv, pf) in enumerate(split.concave)
    ]
    results = iter(decompose_pieces(jobs, params, cache=cache, workers=workers))
    out: dict[str, MeshColliders] = {}
    for name, split in splits.items():
        pieces = [next(results) for _ in split.concave]
        parts = list(split.parts) + [p for r in pieces for p in r.parts]
        out[name] = MeshColliders(parts, len(split.parts), pieces)
    return out
