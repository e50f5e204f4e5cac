"""Meshes as building models author them, for tests: prisms of any plan and walls with their openings cut through
them, each one connected, watertight mesh (not boxes stacked side by side)."""

from __future__ import annotations

import numpy as np
import shapely
import trimesh


def prism(outline: shapely.Polygon, height: float) -> trimesh.Trimesh:
    """`outline` (holes allowed) extruded from z = 0 to `height`, triangulated by shapely (constrained Delaunay)."""
    tris = shapely.get_coordinates(shapely.get_parts(shapely.constrained_delaunay_triangles(outline)))
    vertices, faces = np.unique(tris.reshape(-1, 4, 2)[:, :3].reshape(-1, 2), axis=0, return_inverse=True)
    return trimesh.creation.extrude_triangulation(vertices, faces.reshape(-1, 3), height)


def wall_with_openings(length: float, thickness: float, height: float,
                       openings: list[tuple[float, float, float, float]]) -> trimesh.Trimesh:
    """A wall along +x from the origin, y in [0, thickness], z in [0, height], with rectangular openings
    (x0, x1, z0, z1) through it (z0 = 0: a doorway)."""
    elevation = shapely.box(0, 0, length, height).difference(
        shapely.union_all([shapely.box(x0, z0, x1, z1) for x0, x1, z0, z1 in openings]))
    mesh = prism(elevation, thickness)  # the elevation in the xy plane, the thickness along z
    mesh.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, [1, 0, 0]))  # y -> z, z -> -y
    mesh.apply_translation((0, thickness, 0))
    return mesh
