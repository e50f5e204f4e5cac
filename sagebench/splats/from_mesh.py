"""Mesh to Gaussians: flat, surface-aligned Gaussians spread evenly over a triangle mesh's area.

Samples sit on a square lattice in each face's plane (about area / spacing^2 per face); each Gaussian lies in the surface plane (in-plane sigma from the spacing, a thin axis along the normal)
and takes the surface colour there: vertex colours, texture, face colours or the material's base colour.
"""

from __future__ import annotations

import numpy as np
import trimesh

from sagebench.render.gaussians import Gaussians, logit, rgb_to_sh_dc

LIGHT = np.array([0.35, 0.25, 0.9]) / np.linalg.norm([0.35, 0.25, 0.9])  # baked light direction (towards it)
DEFAULT_RGB = (0.7, 0.7, 0.7)


def sample_surface(mesh: trimesh.Trimesh, spacing: float, rng: np.random.Generator,
                   faces: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Surface samples on a square lattice `spacing` m apart, on the faces where `faces` [F] bool is set.

    Each face takes the points of a lattice laid in its plane, with axes fixed by the face normal
    (in_plane_axes) and a random offset per plane, that fall inside it: coplanar faces share a lattice
    (no seams along the diagonal of a quad), and a face of area A gets A / spacing^2 samples on
    average however small it is. Returns face index [M] int64 and barycentric
    coordinates [M, 3] float64.
    """
    if spacing <= 0:
        raise ValueError(f"spacing must be positive, got {spacing}")
    tri = np.asarray(mesh.triangles, dtype=np.float64)
    normals = np.asarray(mesh.face_normals, dtype=np.float64)
    keep = mesh.area_faces > 0
    if faces is not None:
        keep &= faces
    ids = np.flatnonzero(keep)
    # one random lattice offset per plane (normal and distance from the origin, to 1 um)
    planes = np.round(np.column_stack([normals[ids], np.einsum("fc,fc->f", normals[ids], tri[ids, 0])]), 6)
    _, plane = np.unique(planes, axis=0, return_inverse=True)
    offset = rng.random((plane.max() + 1 if len(plane) else 0, 2))[plane.ravel()]
    t1, t2 = in_plane_axes(normals[ids])
    # vertices in lattice units: [F, 3 corners, 2]
    uv = np.stack([np.einsum("fkc,fc->fk", tri[ids], t1), np.einsum("fkc,fc->fk", tri[ids], t2)], axis=2) / spacing
    uv -= offset[:, None, :]
    lo = np.floor(uv.min(axis=1)).astype(np.int64)
    span = np.ceil(uv.max(axis=1)).astype(np.int64) - lo + 1  # [F, 2] lattice points per axis to try
    n_try = span[:, 0] * span[:, 1]
    owner = np.repeat(np.arange(len(ids)), n_try)
    local = np.arange(n_try.sum()) - np.repeat(np.cumsum(n_try) - n_try, n_try)
    pts = lo[owner] + np.stack([local % span[owner, 0], local // span[owner, 0]], axis=1)
    a, b, c = uv[owner, 0], uv[owner, 1], uv[owner, 2]
    v0, v1, v2 = b - a, c - a, pts - a
    den = v0[:, 0] * v1[:, 1] - v1[:, 0] * v0[:, 1]
    l1 = (v2[:, 0] * v1[:, 1] - v1[:, 0] * v2[:, 1]) / den
    l2 = (v0[:, 0] * v2[:, 1] - v2[:, 0] * v0[:, 1]) / den
    inside = (l1 >= 0) & (l2 >= 0) & (l1 + l2 < 1)
    bary = np.stack([1.0 - l1 - l2, l1, l2], axis=1)[inside]
    return ids[owner[inside]].astype(np.int64), bary


def in_plane_axes(normals: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """[M, 3] unit normals -> two [M, 3] unit axes t1, t2 with (t1, t2, n) right-handed, a function of n alone."""
    n = normals / np.linalg.norm(normals, axis=1, keepdims=True)
    helper = np.where((np.abs(n[:, 0]) < 0.9)[:, None], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0])
    t1 = np.cross(helper, n)
    t1 /= np.linalg.norm(t1, axis=1, keepdims=True)
    return t1, np.cross(n, t1)


def surface_rgb(mesh: trimesh.Trimesh, face: np.ndarray, bary: np.ndarray) -> np.ndarray:
    """[M, 3] colour in [0, 1] at the samples, from whatever colour the mesh carries."""
    visual = mesh.visual
    corners = mesh.faces[face]  # [M, 3] vertex ids
    if visual.kind == "vertex":
        vc = np.asarray(visual.vertex_colors, dtype=np.float64)[:, :3] / 255.0
        return np.einsum("mk,mkc->mc", bary, vc[corners])
    if visual.kind == "face":
        return np.asarray(visual.face_colors, dtype=np.float64)[face, :3] / 255.0
    if visual.kind == "texture":
        material = visual.material
        image = getattr(material, "baseColorTexture", None) or getattr(material, "image", None)
        if image is not None and visual.uv is not None and len(visual.uv) == len(mesh.vertices):
            # glTF multiplies the texture by baseColorFactor; other materials' colour is only a fallback
            base = getattr(material, "baseColorFactor", None)
            factor = np.ones(3) if base is None else np.asarray(base, np.float64)[:3] / 255.0
            uv = np.einsum("mk,mkc->mc", bary, np.asarray(visual.uv, dtype=np.float64)[corners])
            texels = np.asarray(image.convert("RGB"), dtype=np.float64) / 255.0
            h, w = texels.shape[:2]
            col = np.floor(np.mod(uv[:, 0], 1.0) * w).astype(np.int64).clip(0, w - 1)
            row = np.floor((1.0 - np.mod(uv[:, 1], 1.0)) * h).astype(np.int64).clip(0, h - 1)
            return texels[row, col] * factor
        return np.tile(_base_colour(material), (len(face), 1))
    return np.tile(DEFAULT_RGB, (len(face), 1))


def _base_colour(material) -> np.ndarray:
    colour = getattr(material, "baseColorFactor", None)
    if colour is None:
        colour = getattr(material, "main_color", None)
    if colour is None:
        return np.ones(3)
    return np.asarray(colour, dtype=np.float64)[:3] / 255.0


def normal_frames(normals: np.ndarray) -> np.ndarray:
    """[M, 3] unit normals -> [M, 4] wxyz quaternions whose local z axis is the normal."""
    n = normals / np.linalg.norm(normals, axis=1, keepdims=True)
    t1, t2 = in_plane_axes(n)
    return rotmat_to_quat(np.stack([t1, t2, n], axis=2))


def rotmat_to_quat(rot: np.ndarray) -> np.ndarray:
    """[M, 3, 3] rotation matrices -> [M, 4] unit wxyz quaternions with w >= 0."""
    m = rot
    trace = m[:, 0, 0] + m[:, 1, 1] + m[:, 2, 2]
    cand = np.stack([
        np.stack([1 + trace, m[:, 2, 1] - m[:, 1, 2], m[:, 0, 2] - m[:, 2, 0], m[:, 1, 0] - m[:, 0, 1]], 1),
        np.stack([m[:, 2, 1] - m[:, 1, 2], 1 + m[:, 0, 0] - m[:, 1, 1] - m[:, 2, 2], m[:, 0, 1] + m[:, 1, 0],
                  m[:, 0, 2] + m[:, 2, 0]], 1),
        np.stack([m[:, 0, 2] - m[:, 2, 0], m[:, 0, 1] + m[:, 1, 0], 1 - m[:, 0, 0] + m[:, 1, 1] - m[:, 2, 2],
                  m[:, 1, 2] + m[:, 2, 1]], 1),
        np.stack([m[:, 1, 0] - m[:, 0, 1], m[:, 0, 2] + m[:, 2, 0], m[:, 1, 2] + m[:, 2, 1],
                  1 - m[:, 0, 0] - m[:, 1, 1] + m[:, 2, 2]], 1),
    ], axis=1)  # [M, 4 candidates, 4]: candidate c is 4 q_c q, best conditioned where q_c is largest
    diag = np.stack([trace, m[:, 0, 0], m[:, 1, 1], m[:, 2, 2]], axis=1)
    q = cand[np.arange(len(m)), np.argmax(diag, axis=1)]
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    return q * np.where(q[:, :1] < 0, -1.0, 1.0)


def mesh_gaussians(
    mesh: trimesh.Trimesh,
    instance_id: int,
    *,
    spacing: float,
    rng: np.random.Generator,
    faces: np.ndarray | None = None,
    scale_factor: float = 0.7,
    thickness_ratio: float = 0.1,
    opacity: float = 0.95,
    shading: float = 0.35,
) -> Gaussians:
    """Flat Gaussians covering `mesh` (world space; only `faces` [F] bool if given) about `spacing` m apart,
    all tagged `instance_id`.

    In-plane sigma = scale_factor * spacing, normal sigma = thickness_ratio times that. `shading` in
    [0, 1] bakes a soft half-Lambert light (from LIGHT) into the colour so that faces of a single-colour
    object stay distinguishable; 0 keeps the surface colour as is.
    """
    face, bary = sample_surface(mesh, spacing, rng, faces)
    m = len(face)
    tri = mesh.triangles[face]  # [M, 3, 3]
    means = np.einsum("mk,mkc->mc", bary, tri)
    normals = np.asarray(mesh.face_normals, dtype=np.float64)[face]
    rgb = surface_rgb(mesh, face, bary)
    if shading > 0:
        rgb = rgb * ((1.0 - shading) + shading * (0.5 + 0.5 * normals @ LIGHT))[:, None]
    sigma = scale_factor * spacing
    log_scales = np.log(np.array([sigma, sigma, sigma * thickness_ratio]))
    return Gaussians(
        means=means.astype(np.float32),
        quats_wxyz=normal_frames(normals).astype(np.float32),
        log_scales=np.tile(log_scales, (m, 1)).astype(np.float32),
        opacity_logits=np.full(m, logit(opacity), np.float32),
        sh=rgb_to_sh_dc(rgb)[:, None, :],
        instance_id=np.full(m, instance_id, np.int32),
    )
