"""Convex parts within PhysX's 64-vertex hull limit: fewer vertices, inside the original, close to it."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from hypothesis import given
from hypothesis import strategies as st
from scipy.spatial import ConvexHull

from sagebench.collider_export.convex import hull_part
from sagebench.collider_export.vertex_limit import PHYSX_HULL_VERTEX_LIMIT, limit_vertices, within_vertex_limit


def inside(points: np.ndarray, hull_points: np.ndarray, eps: float = 1e-9) -> np.ndarray:
    planes = ConvexHull(hull_points).equations
    return (np.column_stack([points, np.ones(len(points))]) @ planes.T).max(axis=1) <= eps


def test_plant_foliage_icosphere_of_162_vertices_keeps_64_within_6_percent_of_its_radius():
    sphere = hull_part(trimesh.creation.icosphere(subdivisions=2, radius=0.3).vertices)
    assert len(sphere.vertices) == 162
    out = limit_vertices(sphere)
    assert len(out.vertices) == PHYSX_HULL_VERTEX_LIMIT
    assert inside(out.vertices, sphere.vertices).all()  # kept vertices are the part's own
    # how far the lost surface lies outside the reduced hull: at most 6 % of the radius (measured 4.9 %; 64
    # points spread evenly over a sphere leave caps 3.9 % deep)
    planes = ConvexHull(out.vertices).equations
    gap = (np.column_stack([sphere.vertices, np.ones(162)]) @ planes.T).max(axis=1).max()
    assert 0 < gap < 0.06 * 0.3
    assert 0.9 * sphere.volume < out.volume < sphere.volume  # measured 93 %


def test_parts_within_the_limit_are_returned_unchanged():
    box = hull_part(trimesh.creation.box((1, 2, 3)).vertices)
    assert limit_vertices(box) is box
    parts = [box, hull_part(trimesh.creation.icosphere(subdivisions=2).vertices)]
    out = within_vertex_limit(parts)
    assert out[0] is box and len(out[1].vertices) == 64


def test_limit_below_a_tetrahedron_is_refused():
    with pytest.raises(ValueError, match="at least 4"):
        limit_vertices(hull_part(trimesh.creation.box((1, 1, 1)).vertices), 3)


@given(st.integers(4, 40), st.integers(0, 2**32 - 1))
def test_any_point_cloud_hull_keeps_within_the_limit_inside_the_original(limit, seed):
    points = np.random.default_rng(seed).normal(size=(200, 3)) * [1.0, 0.5, 0.2]
    part = hull_part(points)
    out = limit_vertices(part, limit)
    assert len(out.vertices) <= limit
    assert inside(out.vertices, part.vertices).all()
    # outward winding kept: every face normal points away from the centroid
    v, f = out.vertices, out.faces
    n = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    assert np.all(np.einsum("ij,ij->i", n, v[f].mean(axis=1) - v.mean(axis=0)) > 0)
