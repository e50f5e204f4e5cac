"""Door leaves that clear the floor: their collider parts cut a gap above it, as real doors are undercut.

A leaf modelled down to the floor touches it, and a hinged body pressed on the floor by gravity does not swing
(six of the demo's seven doors stood still under 400 N m). Each part is cut by the plane `gap` above the floor
(world z), the part below dropped; USD and MJCF get the same cut parts.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import trimesh

from sagebench.collider_export.bodies import DOOR_FLOOR_GAP_M
from sagebench.collider_export.convex import ConvexPart, hull_part


def clear_floor(parts: Sequence[ConvexPart], matrix: np.ndarray, floor_z: float,
                gap: float = DOOR_FLOOR_GAP_M) -> list[ConvexPart]:
    """`parts` (mesh frame; `matrix` [4, 4] mesh -> world) with everything below floor_z + gap (world z) cut
    away; a part wholly below it is dropped (all of them: the parts as they were)."""
    cut = floor_z + gap
    inverse = np.linalg.inv(matrix)
    out = []
    for part in parts:
        world = trimesh.transform_points(part.vertices, matrix)
        z = world[:, 2]
        if z.min() >= cut:
            out.append(part)
        elif z.max() > cut:
            out.append(hull_part(trimesh.transform_points(_above(world, part.faces, cut), inverse)))
    return out or list(parts)


def _above(vertices: np.ndarray, faces: np.ndarray, cut: float) -> np.ndarray:
    """The vertices [V, 3] of a convex hull at or above z = cut, and where its edges cross that plane."""
    edges = np.unique(np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1), axis=0)
    a, b = vertices[edges[:, 0]], vertices[edges[:, 1]]
    crossing = (a[:, 2] - cut) * (b[:, 2] - cut) < 0
    t = (cut - a[crossing, 2]) / (b[crossing, 2] - a[crossing, 2])
    points = a[crossing] + t[:, None] * (b[crossing] - a[crossing])
    return np.concatenate([vertices[vertices[:, 2] >= cut], points])
