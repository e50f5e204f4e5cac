"""Object footprints the SAGE-3D way: sample the surface, project to the ground, convex hull per part, union.

An L-shaped sofa or a table on four legs is then not one rectangle: each connected part of the mesh
gets its own hull and the hulls are fused.
"""

from __future__ import annotations

import math

import numpy as np
import shapely
import trimesh
from scipy.spatial import ConvexHull, QhullError
from shapely.geometry.base import BaseGeometry

MIN_PART_POINTS = 16  # even a tiny part gets enough samples for a hull


def mesh_parts(mesh: trimesh.Trimesh) -> tuple[np.ndarray, np.ndarray]:
    """Triangles [F, 3, 3] (float64, m) and the connected part [F] (int64, 0..P-1) each belongs to.

    Vertices at the same position are merged first, so a part is a piece whose triangles share edges
    however the file split its vertices (per-face normals, UV seams).
    """
    m = trimesh.Trimesh(vertices=mesh.vertices, faces=mesh.faces, process=False)
    m.merge_vertices(merge_tex=True, merge_norm=True)
    m.update_faces(m.nondegenerate_faces(height=1e-12))
    labels = trimesh.graph.connected_component_labels(m.face_adjacency, node_count=len(m.faces))
    return np.asarray(m.vertices[m.faces], dtype=np.float64), np.asarray(labels, dtype=np.int64)


def sample_surface(tris: np.ndarray, count: int, rng: np.random.Generator) -> np.ndarray:
    """[count, 3] points uniformly distributed over the triangles' area (area-weighted face choice).

    tris: [F, 3, 3] float, m.
    """
    area = 0.5 * np.linalg.norm(np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]), axis=1)
    total = area.sum()
    face = rng.choice(len(tris), size=count, p=area / total) if total > 0 else rng.integers(len(tris), size=count)
    u, v = rng.random(count), rng.random(count)
    flip = u + v > 1
    u, v = np.where(flip, 1 - u, u), np.where(flip, 1 - v, v)
    t = tris[face]
    return t[:, 0] + u[:, None] * (t[:, 1] - t[:, 0]) + v[:, None] * (t[:, 2] - t[:, 0])


def footprint(tris: np.ndarray, part: np.ndarray, density: float, rng: np.random.Generator,
              min_width: float) -> BaseGeometry:
    """The fused ground footprint of one object: a Polygon or MultiPolygon in world xy, m.

    tris: [F, 3, 3] float and part: [F] int from `mesh_parts`; density: sample points per m^2 of surface,
    at least MIN_PART_POINTS per part. A part seen edge-on from above (a vertical panel) has a hull
    of no area; it is widened to `min_width` so it still has a footprint.
    """
    if len(tris) == 0:
        return shapely.Polygon()
    hulls = []
    for p in np.unique(part):
        pt = tris[part == p]
        area = 0.5 * np.linalg.norm(np.cross(pt[:, 1] - pt[:, 0], pt[:, 2] - pt[:, 0]), axis=1).sum()
        n = max(MIN_PART_POINTS, math.ceil(area * density))
        hulls.append(hull_2d(sample_surface(pt, n, rng)[:, :2], min_width))
    return shapely.union_all(hulls)


def hull_2d(points: np.ndarray, min_width: float) -> shapely.Polygon:
    """Convex hull of [N, 2] points as a polygon; a segment or point hull is widened to `min_width`."""
    try:
        poly = shapely.Polygon(points[ConvexHull(points).vertices])
    except QhullError:  # all points on one line or at one point
        poly = shapely.MultiPoint(points).convex_hull
    if poly.area > 1e-6 * poly.length:
        return poly
    # thinner than a micrometre: a vertical panel seen from above becomes a strip along its longest chord
    key = points[:, 0] + 1e-3 * points[:, 1]  # along the chord, whichever way it runs
    a, b = points[np.argmin(key)], points[np.argmax(key)]
    if np.allclose(a, b):
        return shapely.Point(a).buffer(min_width / 2, cap_style="square")
    return shapely.LineString([a, b]).buffer(min_width / 2, cap_style="flat")


def footprint_reference(tris: np.ndarray, part: np.ndarray) -> BaseGeometry:
    """Exact version of `footprint` for polyhedral parts: the union of each part's vertex hull."""
    hulls = [shapely.MultiPoint(tris[part == p].reshape(-1, 3)[:, :2]).convex_hull for p in np.unique(part)]
    return shapely.union_all(hulls)
