"""Surfaces from Gaussians: an L stays an L, a desk keeps its knee space, a box stays its box, a thin base stays
thin, floaters are dropped."""

from __future__ import annotations

import math

import numpy as np
import pytest
import shapely
import trimesh

from sagebench.collider_export.quality import lattice_points
from sagebench.render.gaussians import Gaussians, concat
from sagebench.scene.assets import COLOURS, floor_lamp, table
from sagebench.splat_geometry.surface import (
    SurfaceSettings, gaussian_covariances, gaussian_points, object_surface,
)
from sagebench.splats.from_mesh import mesh_gaussians, normal_frames
from sagebench.topdown.footprints import footprint_reference, mesh_parts
from tests.meshes import prism

L_OUTLINE = shapely.Polygon([(0, 0), (2.0, 0), (2.0, 0.8), (0.8, 0.8), (0.8, 2.0), (0, 2.0)])  # an L-sofa, 2 x 2 m


def _points(mesh: trimesh.Trimesh, spacing: float = 0.02) -> np.ndarray:
    return lattice_points(mesh.triangles, spacing)


def _frame(points: np.ndarray, yaw: float = 0.0):
    """The points' box turned by `yaw`: centre [3], axes [3, 3] (rows), half extents [3]."""
    c, s = math.cos(yaw), math.sin(yaw)
    axes = np.array([[c, s, 0.0], [-s, c, 0.0], [0, 0, 1.0]])
    local = points @ axes.T
    lo, hi = local.min(axis=0), local.max(axis=0)
    return (lo + hi) / 2 @ axes, axes, (hi - lo) / 2


def _footprint(mesh: trimesh.Trimesh) -> shapely.Geometry:
    return footprint_reference(*mesh_parts(mesh))


@pytest.mark.parametrize("yaw", [0.0, 0.6])
def test_an_l_shaped_object_keeps_its_inner_corner(yaw):
    mesh = prism(L_OUTLINE, 0.8)
    mesh.apply_transform(trimesh.transformations.rotation_matrix(yaw, [0, 0, 1]))
    pts = _points(mesh)
    surface = object_surface(pts, np.ones(len(pts)), *_frame(mesh.vertices, yaw))
    got = _footprint(surface)
    truth = shapely.affinity.rotate(L_OUTLINE, yaw, origin=(0, 0), use_radians=True)
    assert got.intersection(truth).area / got.union(truth).area > 0.97
    corner = shapely.affinity.rotate(shapely.Point(1.5, 1.5), yaw, origin=(0, 0), use_radians=True)
    assert not got.buffer(0.1).contains(corner)  # the inner corner stays free (a hull would cover it)
    assert surface.bounds[1][2] == pytest.approx(0.8, abs=0.005)  # no part reaches past the points


def test_a_box_object_is_its_box_in_few_parts():
    mesh = trimesh.creation.box(extents=(0.9, 0.5, 0.75))
    mesh.apply_translation((3, 4, 0.375))
    pts = _points(mesh)
    surface = object_surface(pts, np.ones(len(pts)), *_frame(mesh.vertices))
    assert np.allclose(surface.bounds, mesh.bounds, atol=1e-6)
    assert surface.volume == pytest.approx(mesh.volume, rel=0.01)  # solid: the inside was filled
    assert mesh_parts(surface)[1].max() + 1 <= 2


@pytest.mark.parametrize(("spacing", "below"), [(0.02, 0.01), (0.033, 0.01), (0.033, 0.0)])
def test_a_thin_base_stays_under_the_band(spacing, below):
    """A floor lamp's 3 cm base, its box reaching `below` m under the floor: no part mixing base and pole reaches
    into the band (5 cm up), so only the pole blocks there."""
    base = trimesh.creation.cylinder(radius=0.15, height=0.03)
    base.apply_translation((0, 0, 0.015))
    pole = trimesh.creation.cylinder(radius=0.015, height=1.27)
    pole.apply_translation((0, 0, 0.03 + 0.635))
    pts = np.concatenate([_points(base, spacing), _points(pole, spacing)])
    centre, axes, half = _frame(pts)
    surface = object_surface(pts, np.ones(len(pts)), centre - [0, 0, below / 2], axes, half + [0, 0, below / 2],
                             SurfaceSettings(band=(0.05, 1.2)))
    tris, part = mesh_parts(surface)
    wide = [p for p in np.unique(part) if np.ptp(tris[part == p][..., :2].reshape(-1, 2), axis=0).max() > 0.1]
    assert wide and max(tris[part == p][..., 2].max() for p in wide) < 0.05


@pytest.mark.parametrize("below", [0.0, 0.01, 0.02])
def test_a_plate_keeps_its_thickness(below):
    """Voxels filled inside a 3 cm plate (4 cm voxels) add no height: parts end at the plate's own points."""
    plate = trimesh.creation.box(extents=(0.6, 0.4, 0.03))
    plate.apply_translation((0, 0, 0.015))
    pts = _points(plate, 0.06)  # sparser than the voxels: closing fills voxels that hold no point
    centre, axes, half = _frame(pts)
    surface = object_surface(pts, np.ones(len(pts)), centre - [0, 0, below / 2], axes, half + [0, 0, below / 2])
    assert surface.bounds[:, 2] == pytest.approx([0.0, 0.03], abs=1e-6)


def test_floaters_and_nothing():
    rng = np.random.default_rng(0)
    pts = rng.uniform(-1, 1, (40, 3))  # scattered, one per voxel, below the summed opacity needed
    weights = np.full(len(pts), 0.3)
    box = (np.zeros(3), np.eye(3), np.ones(3))
    assert object_surface(pts, weights, *box) is None
    dense = np.concatenate([pts, _points(trimesh.creation.box(extents=(0.4, 0.4, 0.4)))])
    surface = object_surface(dense, np.concatenate([weights, np.ones(len(dense) - len(pts))]), *box)
    assert np.allclose(surface.bounds, [[-0.2] * 3, [0.2] * 3], atol=1e-6)  # the floaters are left out


def test_parts_are_capped():
    rng = np.random.default_rng(1)
    blobs = np.concatenate([_points(trimesh.creation.box(extents=(0.1, 0.1, 0.1)).apply_translation(c))
                            for c in rng.uniform(-1, 1, (40, 3))])
    surface = object_surface(blobs, np.ones(len(blobs)), np.zeros(3), np.eye(3), np.full(3, 1.1),
                             SurfaceSettings(max_parts=5))
    assert mesh_parts(surface)[1].max() + 1 <= 5


def test_wide_gaussians_stand_for_more_than_their_centre():
    means = np.array([[0, 0, 0], [1, 0, 0]], np.float32)
    log_scales = np.log(np.array([[0.2, 0.01, 0.01], [0.01, 0.01, 0.01]], np.float32))
    turn = [math.cos(math.pi / 4), 0, 0, math.sin(math.pi / 4)]  # 90 degrees about z: local x along world y
    g = Gaussians(means, np.array([turn, [1, 0, 0, 0]], np.float32), log_scales, np.zeros(2, np.float32),
                  np.zeros((2, 1, 3), np.float32), np.zeros(2, np.int32))
    points, weights, source = gaussian_points(g, voxel=0.04)
    assert source.tolist() == [0, 1, 0, 0]
    assert np.allclose(points[2:], [[0, 0.2, 0], [0, -0.2, 0]], atol=1e-6)
    assert weights.tolist() == pytest.approx([0.5] * 4)


@pytest.mark.parametrize("yaw", [0.0, 0.6])
def test_a_desk_keeps_its_knee_space(yaw):
    """A desk (a 4 cm top on four 5 cm legs, 0.75 m high): the space under the top between the legs stays free of
    every part (one hull of the desk, or its box, would fill it), and the top and legs are kept."""
    mesh = table(1.2, 0.6, 0.75, COLOURS["white"])
    turn = trimesh.transformations.rotation_matrix(yaw, [0, 0, 1])
    mesh.apply_transform(turn)
    pts = _points(mesh)
    surface = object_surface(pts, np.ones(len(pts)), *_frame(mesh.vertices, yaw))
    tris, part = mesh_parts(surface)
    hulls = [trimesh.convex.convex_hull(tris[part == p].reshape(-1, 3)) for p in np.unique(part)]
    knee = trimesh.transformations.transform_points(
        np.array([[x, y, z] for x in (-0.4, 0, 0.4) for y in (-0.15, 0, 0.15) for z in (0.1, 0.35, 0.6)]), turn)
    assert not any(h.contains(knee).any() for h in hulls)
    assert surface.bounds[:, 2] == pytest.approx([0.0, 0.75], abs=0.005)
    under_legs = trimesh.transformations.transform_points(np.array([[sx * 0.55, sy * 0.25, 0.35]
                                                                   for sx in (-1, 1) for sy in (-1, 1)]), turn)
    assert all(any(h.contains([p])[0] for h in hulls) for p in under_legs)


@pytest.mark.parametrize("face", [0.0, 0.4, 2.0])
def test_a_pole_seen_from_one_side_is_round_and_as_thick_as_its_splats(face):
    """A floor lamp whose 3 cm pole (radius 1.5 cm) shows one column of flat splats (sigma 2.3 cm in their plane,
    0.23 cm across) on the face at angle `face`: the post in the band reaches 1.1 cm past the pole's axis on every
    side (a grazing agent touches it, whichever side it passes) and stays within 2 cm of the axis (it was a square
    4.7 cm wide around the splats, 1.5 cm off the axis: it reached a map cell past the pole)."""
    mesh = floor_lamp(0.4, 0.4, 1.6, COLOURS["white"])
    g = mesh_gaussians(mesh, 1, spacing=1 / 30, rng=np.random.default_rng(0))
    pole = (np.linalg.norm(g.means[:, :2], axis=1) < 0.02) & (g.means[:, 2] > 0.03) & (g.means[:, 2] < 1.3)
    g = g.take(np.flatnonzero(~pole))
    z = np.arange(0.05, 1.28, 1 / 30)
    normal = np.tile([math.cos(face), math.sin(face), 0.0], (len(z), 1))
    f32 = np.float32
    g = concat([g, Gaussians((0.015 * math.cos(math.pi / 16) * normal + np.c_[0 * z, 0 * z, z]).astype(f32),
                             normal_frames(normal).astype(f32), np.log([[0.023, 0.023, 0.0023]] * len(z)).astype(f32),
                             np.full(len(z), 3.0, f32), np.zeros((len(z), 1, 3), f32), np.ones(len(z), np.int32))])
    points, weights, source = gaussian_points(g, 0.04)
    surface = object_surface(points, weights, *_frame(mesh.vertices), SurfaceSettings(band=(0.05, 1.2)),
                             gaussian_covariances(g)[source])
    tris, part = mesh_parts(surface)
    post = np.concatenate([tris[part == p].reshape(-1, 3) for p in np.unique(part)
                           if tris[part == p][..., 2].min() < 0.6 < tris[part == p][..., 2].max()])[:, :2]
    turns = np.arange(16) * math.pi / 8
    assert ((post @ np.stack([np.cos(turns), np.sin(turns)])).max(axis=0) >= 0.011).all()
    assert np.linalg.norm(post, axis=1).max() <= 0.02
