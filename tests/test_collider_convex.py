"""Convex-piece detection: exact parts for boxes and cylinders, concave pieces left for CoACD."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from scipy.spatial import ConvexHull
from hypothesis import given, settings
from hypothesis import strategies as st

from profiles import examples

from sagebench.collider_export.convex import (
    FLAT_BRIDGE,
    MIN_THICKNESS,
    face_components,
    hull_part,
    is_convex_solid,
    is_convex_solid_reference,
    merge_parts,
    split_convex,
    weld,
)


def u_prism(width: float = 0.6, depth: float = 0.4, wall: float = 0.15, height: float = 0.3) -> trimesh.Trimesh:
    """A closed U-shaped extrusion (concave, volume known in closed form)."""
    w, d, t = width, depth, wall
    pts = np.array([(0, 0), (w, 0), (w, 0.1), (w, d), (w - t, d), (w - t, 0.1), (t, 0.1), (t, d), (0, d), (0, 0.1)])
    tris = np.array([(0, 1, 2), (0, 2, 5), (0, 5, 6), (0, 6, 9), (5, 2, 3), (5, 3, 4), (9, 6, 7), (9, 7, 8)])
    return trimesh.creation.extrude_triangulation(pts, tris, height)


def test_u_prism_fixture_is_what_it_claims():
    m = u_prism()
    assert m.is_watertight and np.isclose(m.volume, (0.6 * 0.1 + 2 * 0.15 * 0.3) * 0.3)


def test_weld_merges_duplicated_vertices_of_a_triangle_soup():
    box = trimesh.creation.box((1, 2, 3))
    soup_v = box.vertices[box.faces].reshape(-1, 3)
    soup_f = np.arange(len(soup_v)).reshape(-1, 3)
    v, f = weld(soup_v, soup_f)
    assert len(v) == 8 and len(f) == 12
    assert np.allclose(trimesh.Trimesh(v, f).volume, 6.0)


def test_face_components_separates_concatenated_boxes():
    parts = [trimesh.creation.box((1, 1, 1)).apply_translation((3 * i, 0, 0)) for i in range(3)]
    m = trimesh.util.concatenate(parts)
    comps = face_components(m.faces, len(m.vertices))
    assert [len(c) for c in comps] == [12, 12, 12]


def test_boxes_and_cylinders_are_exact_parts():
    parts = [trimesh.creation.box((1, 0.5, 0.2)), trimesh.creation.cylinder(0.1, 1.0, sections=16)]
    parts[1].apply_translation((2, 0, 0))
    m = trimesh.util.concatenate(parts)
    split = split_convex(m.vertices, m.faces)
    assert split.concave == []
    assert sorted(round(p.volume, 6) for p in split.parts) == sorted(round(p.volume, 6) for p in parts)


def test_boxes_touching_at_corners_stay_separate_parts():
    """A tub of five boxes whose corners coincide (one vertex-connected piece) is still five exact parts."""
    base = trimesh.creation.box((1.0, 0.6, 0.06)).apply_translation((0, 0, 0.03))
    wall = trimesh.creation.box((1.0, 0.06, 0.5)).apply_translation((0, 0.27, 0.25))
    m = trimesh.util.concatenate([base, wall])
    split = split_convex(m.vertices, m.faces)
    assert split.concave == [] and len(split.parts) == 2


def test_u_prism_is_left_for_coacd():
    m = u_prism()
    split = split_convex(m.vertices, m.faces)
    assert split.parts == [] and len(split.concave) == 1
    v, f = split.concave[0]
    assert np.isclose(trimesh.Trimesh(v, f).volume, m.volume)


def test_flat_piece_becomes_a_padded_part():
    quad_v = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float)
    quad_f = np.array([[0, 1, 2], [0, 2, 3]])
    split = split_convex(quad_v, quad_f)
    (part,) = split.parts
    assert np.isclose(np.ptp(part.vertices[:, 2]), MIN_THICKNESS)
    assert np.isclose(part.volume, MIN_THICKNESS)


@pytest.mark.parametrize("notch", [0.004, 0.3])
def test_flat_piece_with_a_notch_is_its_hull_only_when_the_notch_is_shallow(notch):
    """A U-shaped sheet (a grand piano's lid is one, curved): its hull fills the notch, so it is left for the
    methods, which measure it; a notch shallower than FLAT_BRIDGE is no notch."""
    u = u_prism(depth=0.1 + notch, height=1.0)
    top = u.faces[np.isclose(u.vertices[u.faces][:, :, 2], 1.0).all(axis=1)]  # the U outline, one sheet at z = 1
    split = split_convex(u.vertices + [0, 0, 0.5], top)
    if notch < FLAT_BRIDGE:
        assert len(split.parts) == 1 and split.concave == []
    else:
        assert split.parts == [] and len(split.concave) == 1


def test_hull_part_is_closed_and_outward():
    part = hull_part(np.random.default_rng(0).normal(size=(50, 3)))
    mesh = trimesh.Trimesh(part.vertices, part.faces)
    assert mesh.is_watertight and mesh.volume > 0 and np.isclose(mesh.volume, part.volume)


@pytest.mark.parametrize("seed", range(4))
def test_hull_part_of_a_long_thin_cloud_faces_outward(seed):
    # like a voxel box of a bed's rail: 1.1 m long, a few cm across, thousands of points, many coplanar (on
    # the real one, 155,000 lattice points, trimesh's hull wound faces inward and then needed networkx)
    rng = np.random.default_rng(seed)
    pts = rng.random((20000, 3)) * [1.1, 0.043, 0.057]
    pts[: len(pts) // 2, rng.integers(0, 3)] = 0.0  # half of them on one face: many coplanar points
    part = hull_part(pts)
    normals = np.cross(*(part.vertices[part.faces[:, k]] - part.vertices[part.faces[:, 0]] for k in (1, 2)))
    area = np.linalg.norm(normals, axis=1)
    centre = part.vertices.mean(axis=0)
    outward = np.einsum("ij,ij->i", normals, part.vertices[part.faces[:, 0]] - centre)
    assert np.all(outward[area > 1e-12] > 0)
    assert np.isclose(trimesh.Trimesh(part.vertices, part.faces, process=False).volume, ConvexHull(pts).volume)


@st.composite
def solids(draw):
    """A random box, a random convex hull, or a random U prism (concave), in a random pose."""
    kind = draw(st.sampled_from(["box", "hull", "u"]))
    seed = draw(st.integers(0, 2**31 - 1))
    rng = np.random.default_rng(seed)
    if kind == "box":
        m = trimesh.creation.box(rng.uniform(0.05, 2.0, 3))
    elif kind == "hull":
        m = trimesh.convex.convex_hull(rng.normal(size=(30, 3)))
    else:
        m = u_prism(width=rng.uniform(0.5, 1.0), wall=rng.uniform(0.05, 0.2), height=rng.uniform(0.1, 1.0))
    m.apply_transform(trimesh.transformations.random_rotation_matrix(rng.random(3)))
    return kind, m


@settings(max_examples=examples(40))
@given(solids())
def test_volume_test_agrees_with_face_plane_reference(case):
    kind, m = case
    fast = is_convex_solid(m.vertices, m.faces, tolerance=0.002)
    assert fast == is_convex_solid_reference(m.vertices, m.faces)
    assert fast == (kind != "u")


def test_open_box_is_not_a_convex_solid():
    box = trimesh.creation.box((1, 1, 1))
    assert not is_convex_solid(box.vertices, box.faces[:-2], tolerance=0.002)
    assert not is_convex_solid_reference(box.vertices, box.faces[:-2])


def test_merge_parts_merges_above_the_agent_band_first():
    """Two boxes 0.3 m apart in the band and two 0.6 m apart above it: with the band, the far pair above it is
    merged (the space between costs 2 %); without, the near pair."""
    def box(x, z):
        return hull_part(trimesh.creation.box((0.1, 0.1, 0.1)).apply_translation((x, 0, z)).vertices)

    low = [box(0.0, 0.5), box(0.4, 0.5)]
    high = [box(2.0, 2.0), box(2.7, 2.0)]
    with_band = merge_parts(low + high, 3, band=(0.05, 1.2))
    assert sorted(np.ptp(p.vertices[:, 0]) for p in with_band) == pytest.approx([0.1, 0.1, 0.8])
    without = merge_parts(low + high, 3)
    assert sorted(np.ptp(p.vertices[:, 0]) for p in without) == pytest.approx([0.1, 0.1, 0.5])


def test_a_closed_mesh_whose_volumes_cancel_is_not_convex_and_warns_nothing():
    """An octahedron with every face above z = 0 flipped: closed, signed volume 0 (trimesh's centre of mass then
    divides by zero; a user saw eight RuntimeWarnings from one catalogue scene's export)."""
    import warnings

    v = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], dtype=np.float64)
    ring = [0, 2, 1, 3]
    top = [[ring[i], ring[(i + 1) % 4], 4] for i in range(4)]
    bottom = [[ring[(i + 1) % 4], ring[i], 5] for i in range(4)]
    f = np.array([t[::-1] for t in top] + bottom)
    assert trimesh.Trimesh(v, f, process=False).is_watertight
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert not is_convex_solid(v, f, tolerance=0.002)
        assert not is_convex_solid_reference(v, f)
