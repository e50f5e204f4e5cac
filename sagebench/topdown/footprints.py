"""Footprints: objects the SAGE-3D way (sample the surface, project, convex hull per part, union), walls by
their cross-section in the agent's height band.

An L-shaped sofa or a table on four legs is then not one rectangle: each connected part of the mesh
gets its own hull and the hulls are fused. A wall with door openings is one connected part, whose hull
would span every doorway; its band section keeps them open. `object_footprints` is build-scene's step: the
footprint of every object of a scene, walls by their section, everything else by its hulls.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import TYPE_CHECKING

import numpy as np
import shapely
import trimesh
from scipy.spatial import ConvexHull, QhullError
from shapely.geometry.base import BaseGeometry

from sagebench.ui import track

if TYPE_CHECKING:
    from sagebench.scene.loader import LoadedScene
    from sagebench.settings.build_scene import BuildSceneConfig

MIN_PART_POINTS = 16  # even a tiny part gets enough samples for a hull
BAND_SECTION_KINDS = frozenset({"wall"})  # footprint: where they stand in the band (doorways stay open), not hulls
Parts = tuple[np.ndarray, np.ndarray]  # one mesh's `mesh_parts`: tris [F, 3, 3] float64 m, part [F] int64


def object_footprints(scene: LoadedScene, parts: Mapping[int, Parts], band: tuple[float, float],
                      config: BuildSceneConfig) -> dict[int, BaseGeometry]:
    """Instance id -> footprint of every object of the scene (Polygon or MultiPolygon, world xy, m).

    A wall is its `band_section` in `band` (world z lo, hi, m); anything else the `footprint` of its `parts`
    (instance id -> `mesh_parts`), sampled at `config.sample_density` with a generator seeded by (`config.seed`,
    instance id). Each is simplified by a tenth of a cell (`config.resolution`), which drops the near-collinear
    sample and section corners.
    """
    res = config.resolution
    out: dict[int, BaseGeometry] = {}
    for o in track(scene.spec.objects, "footprints"):
        if o.kind in BAND_SECTION_KINDS:
            fp = band_section(scene.meshes[o.instance_id], *band, min_width=res)
        else:
            tris, part = parts[o.instance_id]
            rng = np.random.default_rng([config.seed, o.instance_id])
            fp = footprint(tris, part, config.sample_density, rng, min_width=res)
        out[o.instance_id] = fp.simplify(res / 10)
    return out


def mesh_parts(mesh: trimesh.Trimesh) -> Parts:
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


def band_section(mesh: trimesh.Trimesh, z_lo: float, z_hi: float, min_width: float) -> BaseGeometry:
    """Where a structure stands in the height band [z_lo, z_hi], seen from above: a Polygon or MultiPolygon, m.

    A wall with door openings is one connected part, so the hull of its parts would span every doorway;
    its horizontal cross-sections keep the openings. Between two consecutive vertex heights a mesh of
    vertical faces keeps one cross-section, so one cut at each such interval's middle inside the band
    sees every shape the band holds, and the footprint is their union. Each cut's segments are noded
    and polygonised; a face counts as solid when the mesh lies over or under it there (a wall's top or
    bottom), so the room inside a ring of walls, with nothing of the wall above it, stays out. Section
    lines that bound no solid face (an open sheet of a wall) are widened to `min_width`.
    """
    z = mesh.vertices[:, 2]
    if len(mesh.faces) == 0 or z.max() < z_lo or z.min() > z_hi:
        return shapely.Polygon()
    levels = np.unique(np.concatenate([[z_lo, z_hi], z[(z > z_lo) & (z < z_hi)]]))
    heights = (levels[:-1] + levels[1:]) / 2
    lines, to_world, _ = trimesh.intersections.mesh_multiplane(mesh, [0.0, 0.0, 0.0], [0.0, 0.0, 1.0], heights)
    flat = _flat_triangles(mesh.triangles)
    cuts = []
    for segs, matrix in zip(lines, to_world):
        if len(segs) == 0:
            continue
        pts = trimesh.transform_points(np.column_stack([segs.reshape(-1, 2), np.zeros(2 * len(segs))]), matrix)
        net = shapely.union_all(shapely.set_precision(shapely.linestrings(pts[:, :2].reshape(-1, 2, 2)), 1e-7))
        faces = shapely.get_parts(shapely.polygonize([net]))
        if len(faces):
            faces = faces[_covered(shapely.get_coordinates(shapely.point_on_surface(faces)), flat)]
        solid = shapely.union_all(faces)
        cuts.append(shapely.union(solid, net.difference(solid).buffer(min_width / 2, cap_style="flat")))
    return shapely.union_all(cuts)


def _flat_triangles(tris: np.ndarray) -> np.ndarray:
    """The triangles [F', 3, 3] of [F, 3, 3] that are not seen edge-on from above."""
    a, b, c = tris[:, 0, :2], tris[:, 1, :2], tris[:, 2, :2]
    area2 = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])
    return tris[np.abs(area2) > 1e-12]


def _covered(points: np.ndarray, tris: np.ndarray) -> np.ndarray:
    """[P] bool: some triangle of `tris` [F, 3, 3] (none vertical) lies over or under each xy point [P, 2]."""
    if len(tris) == 0:
        return np.zeros(len(points), dtype=bool)
    a, b, c = (tris[None, :, k, :2] for k in range(3))
    p = points[:, None, :]

    def cross(u, v, w):  # z of (v - u) x (w - u)
        return (v[..., 0] - u[..., 0]) * (w[..., 1] - u[..., 1]) - (v[..., 1] - u[..., 1]) * (w[..., 0] - u[..., 0])

    d1, d2, d3 = cross(a, b, p), cross(b, c, p), cross(c, a, p)
    inside = ((d1 >= -1e-12) & (d2 >= -1e-12) & (d3 >= -1e-12)) | ((d1 <= 1e-12) & (d2 <= 1e-12) & (d3 <= 1e-12))
    return inside.any(axis=1)
