"""Convex parts within PhysX's hull vertex limit, so Isaac Sim collides with the very hulls MuJoCo does.

PhysX cooks a convex mesh of at most 64 vertices; given more it builds its own smaller hull at load time,
which then differs from the part MuJoCo and the collider quality measure use. A part over the limit is
replaced here by the hull of the vertices a greedy farthest-point choice keeps: start from an extreme
tetrahedron, add the vertex farthest outside the current hull until the limit. The result lies inside the
original hull and touches it at every kept vertex (an icosphere of 162 vertices and radius r keeps 93 % of
its volume, no point of it farther than 0.05 r outside; 64 points cannot cover a sphere much closer).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from scipy.spatial import ConvexHull

from sagebench.collider_export.convex import ConvexPart, oriented_hull

PHYSX_HULL_VERTEX_LIMIT = 64  # PhysX's convex mesh cooking limit (PxConvexMeshDesc vertexLimit, at most 64)


def within_vertex_limit(parts: Sequence[ConvexPart], limit: int = PHYSX_HULL_VERTEX_LIMIT) -> list[ConvexPart]:
    """`parts` with each part over `limit` vertices replaced by limit_vertices(part)."""
    return [limit_vertices(p, limit) if len(p.vertices) > limit else p for p in parts]


def limit_vertices(part: ConvexPart, limit: int = PHYSX_HULL_VERTEX_LIMIT) -> ConvexPart:
    """The hull of at most `limit` (>= 4) of the part's vertices [V, 3], chosen greedily farthest outside the
    hull of those chosen before; the part itself when it has no more than `limit`."""
    if limit < 4:
        raise ValueError(f"limit must be at least 4 (a tetrahedron), got {limit}")
    v = np.asarray(part.vertices, dtype=np.float64)
    if len(v) <= limit:
        return part
    chosen = _extreme_tetrahedron(v)
    homogeneous = np.column_stack([v, np.ones(len(v))])
    while len(chosen) < limit:
        planes = ConvexHull(v[chosen]).equations  # [F, 4], outward unit normals: n . x + d > 0 outside
        outside = (homogeneous @ planes.T).max(axis=1)  # [V] distance beyond the farthest-facing plane
        far = int(np.argmax(outside))
        if outside[far] <= 0.0:
            break
        chosen.append(far)
    return ConvexPart(*oriented_hull(v[np.sort(chosen)]))


def _extreme_tetrahedron(v: np.ndarray) -> list[int]:
    """Indices of four vertices spanning a volume: the two farthest apart along x (then y, z), the farthest
    from their line, the farthest from the plane of those three."""
    spans = np.ptp(v, axis=0)
    axis = int(np.argmax(spans))
    a, b = int(np.argmin(v[:, axis])), int(np.argmax(v[:, axis]))
    line = (v[b] - v[a]) / np.linalg.norm(v[b] - v[a])
    off = (v - v[a]) - np.outer((v - v[a]) @ line, line)
    c = int(np.argmax(np.linalg.norm(off, axis=1)))
    normal = np.cross(v[b] - v[a], v[c] - v[a])
    d = int(np.argmax(np.abs((v - v[a]) @ normal)))
    return [a, b, c, d]
