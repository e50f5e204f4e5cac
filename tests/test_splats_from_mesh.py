"""Mesh to Gaussians: density, on-surface placement, flat along the normal, colours from every source."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from PIL import Image

from sagebench.render.gaussians import SH_C0
from sagebench.render.splat_reference import quat_to_rotmat
from sagebench.splats.from_mesh import mesh_gaussians, normal_frames, sample_surface


def _rgb(g) -> np.ndarray:
    return g.sh[:, 0, :] * SH_C0 + 0.5


def test_box_gets_area_over_spacing_squared_flat_gaussians_on_its_faces():
    box = trimesh.creation.box(extents=(1.0, 2.0, 0.5))
    g = mesh_gaussians(box, 12, spacing=0.05, rng=np.random.default_rng(0), shading=0.0)
    assert abs(g.count - box.area / 0.05**2) < 0.03 * box.area / 0.05**2
    assert (g.instance_id == 12).all()
    # every centre lies on the box surface
    on_face = np.isclose(np.abs(g.means), [0.5, 1.0, 0.25], atol=1e-5).any(axis=1)
    assert on_face.all()
    # local z axis (the thin one) is the face normal; scales: in-plane 0.7 * spacing, thin 10% of that
    normals = quat_to_rotmat(g.quats_wxyz)[:, :, 2]
    expected = np.where(np.isclose(np.abs(g.means), [0.5, 1.0, 0.25], atol=1e-5), np.sign(g.means), 0.0)
    assert np.allclose(normals, expected, atol=1e-5)
    assert np.allclose(np.exp(g.log_scales), [0.035, 0.035, 0.0035], rtol=1e-5)


def test_lattice_is_even_on_a_plane():
    plane = trimesh.Trimesh(vertices=[[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], faces=[[0, 1, 2], [0, 2, 3]])
    face, bary = sample_surface(plane, 0.1, np.random.default_rng(3))
    pts = np.einsum("mk,mkc->mc", bary, plane.triangles[face])
    assert len(pts) == 100  # a 10 x 10 lattice with a random offset, no seam along the diagonal
    d = np.linalg.norm(pts[:, None, :2] - pts[None, :, :2], axis=2) + np.eye(len(pts))
    assert d.min(axis=1) == pytest.approx(np.full(len(pts), 0.1))


def test_same_seed_same_gaussians_and_tiny_faces_are_not_lost_on_average():
    sphere = trimesh.creation.icosphere(subdivisions=3, radius=0.3)
    a = mesh_gaussians(sphere, 1, spacing=0.05, rng=np.random.default_rng(5))
    b = mesh_gaussians(sphere, 1, spacing=0.05, rng=np.random.default_rng(5))
    assert a.means.tobytes() == b.means.tobytes()
    assert abs(a.count - sphere.area / 0.05**2) < 0.05 * sphere.area / 0.05**2


def test_colours_from_vertex_face_texture_and_material():
    box = trimesh.creation.box(extents=(1, 1, 1))
    box.visual = trimesh.visual.ColorVisuals(box, vertex_colors=np.tile([255, 0, 0, 255], (8, 1)))
    assert np.allclose(_rgb(mesh_gaussians(box, 1, spacing=0.1, rng=np.random.default_rng(0), shading=0)), [1, 0, 0],
                       atol=1e-5)

    box = trimesh.creation.box(extents=(1, 1, 1))
    box.visual = trimesh.visual.ColorVisuals(box, face_colors=np.tile([0, 0, 255, 255], (12, 1)))
    assert np.allclose(_rgb(mesh_gaussians(box, 1, spacing=0.1, rng=np.random.default_rng(0), shading=0)), [0, 0, 1],
                       atol=1e-5)

    # a texture whose left half is green and right half white, u along x on a unit square
    quad = trimesh.Trimesh(vertices=[[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], faces=[[0, 1, 2], [0, 2, 3]],
                           process=False)
    image = np.full((4, 8, 3), 255, np.uint8)
    image[:, :4] = [0, 255, 0]
    quad.visual = trimesh.visual.TextureVisuals(uv=quad.vertices[:, :2], image=Image.fromarray(image))
    g = mesh_gaussians(quad, 1, spacing=0.05, rng=np.random.default_rng(0), shading=0)
    left = g.means[:, 0] < 0.45
    assert np.allclose(_rgb(g)[left], [0, 1, 0], atol=1e-5)
    assert np.allclose(_rgb(g)[g.means[:, 0] > 0.55], [1, 1, 1], atol=1e-5)

    material = trimesh.visual.material.PBRMaterial(baseColorFactor=[51, 102, 204, 255])
    quad.visual = trimesh.visual.TextureVisuals(material=material)
    g = mesh_gaussians(quad, 1, spacing=0.1, rng=np.random.default_rng(0), shading=0)
    assert np.allclose(_rgb(g), [0.2, 0.4, 0.8], atol=1e-5)


def test_shading_darkens_faces_turned_from_the_light():
    box = trimesh.creation.box(extents=(1, 1, 1))
    g = mesh_gaussians(box, 1, spacing=0.1, rng=np.random.default_rng(0), shading=0.5)
    top, bottom = g.means[:, 2] > 0.49, g.means[:, 2] < -0.49
    assert _rgb(g)[top].mean() > _rgb(g)[bottom].mean() > 0.5 * _rgb(g)[top].mean()


def test_normal_frames_are_rotations_with_z_along_the_normal():
    n = np.random.default_rng(0).normal(size=(500, 3))
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    rot = quat_to_rotmat(normal_frames(n))
    assert np.allclose(rot[:, :, 2], n, atol=1e-9)
    assert np.allclose(np.linalg.det(rot), 1.0)
