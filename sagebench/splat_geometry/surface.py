"""An object's surface from its own Gaussians: an opacity-weighted voxel solid, covered by boxes, each box the
convex hull of the Gaussians inside it.

Why this method (measured on the synth scenes' round trip, see docs/interiorgs.md): the paper's footprint is
the convex hull of surface points per part, and what the agent bumps into is the object's extent in its
height band. A convex hull of all of an object's Gaussians fills an L-sofa's inner corner and a desk's knee
space; marching cubes over a density field gives a smooth but thick surface (half a voxel of bias on every
side and thousands of triangles per object, all for CoACD to decompose again). Here the voxels only decide
*which* Gaussians go together: the solid (voxels whose summed opacity passes `min_weight`, gaps of one voxel
closed, the inside filled) is covered greedily by boxes in the object's own frame, at most `max_parts` of them
(merged where the band footprint allows, as the voxel colliders do), and each box becomes the hull of the
Gaussian points it holds and of the corners of its solid voxels that hold none (the inside), those corners
kept within the range of the box's own points, so no part reaches past the Gaussians themselves (a 3 cm lamp
base stays 3 cm thick, not a voxel's 4). Every part is a separate closed
convex piece: the footprint's hull-per-part keeps concave outlines concave, and the collider export takes
each piece as it is, without decomposing it.

Voxel layers are laid so that one boundary is the band's lower edge: a part never mixes points from under the
band with points in it, so a lamp's base under the band does not come out reaching into it.

A Gaussian counts by its centre and, where it is wider than a voxel along an axis, by the two points one
standard deviation along that axis (a large flat splat covers more than its centre).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import trimesh
from scipy import ndimage

from sagebench.collider_export.convex import hull_part
from sagebench.collider_export.voxel import band_outside, greedy_boxes, layer_weights, merge_boxes
from sagebench.render.gaussians import Gaussians

MAX_VOXELS = 2**25  # voxels of one object's grid at most: its weights, labels and masks take about 0.8 GB
_BLOCK = 2**16  # Gaussians whose covariances are computed at a time: float64 temporaries of a few MB
_CORNER_INSET = 1e-3  # enclosed cells contribute their corners pulled this fraction of a voxel inwards, so that
# two boxes' hulls never share a point (a shared edge would join them into one part, one hull, for the footprint)
_POST_SIDES = 16  # sides of a post's prism: its outline is round to 2 % of its radius


@dataclass(frozen=True)
class SurfaceSettings:
    """How an object's Gaussians become its surface (metres)."""

    voxel: float = 0.04  # voxel side
    min_weight: float = 0.5  # summed opacity a voxel needs to count as occupied
    max_parts: int = 24  # convex parts per object at most
    band: tuple[float, float] | None = None  # the agent's height band (world z), where merged parts must stay tight


def gaussian_points(g: Gaussians, voxel: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The points [M, 3] (world m), weights [M] (opacity) and source Gaussian [M] (index into `g`) that stand for
    the Gaussians: every centre, and centre +- one standard deviation along each axis wider than a voxel."""
    alpha = 1.0 / (1.0 + np.exp(-g.opacity_logits.astype(np.float64)))
    means = g.means.astype(np.float64)
    sigma = np.exp(g.log_scales.astype(np.float64))  # [N, 3]
    rows, axis = np.nonzero(sigma > voxel)
    source = np.arange(g.count)
    if not len(rows):
        return means, alpha, source
    rot = quat_matrices(g.quats_wxyz[rows])  # [K, 3, 3]
    step = rot[np.arange(len(rows)), :, axis] * sigma[rows, axis][:, None]  # [K, 3]: column `axis` of R, scaled
    extra = np.concatenate([means[rows] + step, means[rows] - step])
    return (np.concatenate([means, extra]), np.concatenate([alpha, alpha[rows], alpha[rows]]),
            np.concatenate([source, rows, rows]))


def quat_matrices(q_wxyz: np.ndarray) -> np.ndarray:
    """[N, 4] wxyz quaternions (any norm) -> [N, 3, 3] rotation matrices."""
    q = np.asarray(q_wxyz, dtype=np.float64)
    w, x, y, z = (q / np.linalg.norm(q, axis=1, keepdims=True)).T
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], axis=-1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], axis=-1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], axis=-1),
    ], axis=1)


def grid_voxels(half: np.ndarray, pitch: float) -> float:
    """Voxels of the grid object_surface lays over a box of half extents `half` [3] (m) at `pitch`, at most (a
    float, so that a box of kilometres at a micrometre pitch is counted, not allocated)."""
    return math.prod(float(np.floor(2 * h / pitch)) + 4 for h in np.asarray(half, dtype=np.float64))


def gaussian_covariances(g: Gaussians) -> np.ndarray:
    """[N, 3, 3] each Gaussian's covariance (world m^2): R diag(sigma^2) R^T. Computed _BLOCK Gaussians at a time:
    the float64 temporaries of a whole scene cost more in page faults than the arithmetic."""
    out = np.empty((g.count, 3, 3))
    for a in range(0, g.count, _BLOCK):
        rot = quat_matrices(g.quats_wxyz[a:a + _BLOCK])
        var = np.exp(2 * g.log_scales[a:a + _BLOCK].astype(np.float64))
        out[a:a + _BLOCK] = np.einsum("nij,nj,nkj->nik", rot, var, rot)
    return out


def object_surface(points: np.ndarray, weights: np.ndarray, centre: np.ndarray, axes: np.ndarray,
                   half: np.ndarray, settings: SurfaceSettings = SurfaceSettings(),
                   cov: np.ndarray | None = None) -> trimesh.Trimesh | None:
    """The surface (world m) of the object whose Gaussian points [N, 3] and weights [N] lie in the box
    (centre [3], axes [3, 3] rows, the most vertical last, half extents [3]); None when no voxel is occupied.

    Points outside the box are pulled onto it first, so the surface never reaches past the annotated box. With
    `cov` [N, 3, 3], the covariance of each point's Gaussian, a part narrower across than its Gaussians is widened
    (`_as_wide_as_gaussians`): a plate to one standard deviation of its Gaussians (their median) either side of
    its middle, a post (a pole, a chair's leg) to a round post behind its splats in which every Gaussian lies at
    least its own narrowest standard deviation deep: a pole as thick as its splats, not a sliver.
    """
    pitch = settings.voxel
    local = np.clip((np.asarray(points, dtype=np.float64) - centre) @ axes.T, -half, half)
    lo = -half - pitch  # one empty voxel of margin all round, so closing and filling see the outside
    if settings.band is not None and axes[2, 2] > 1 - 1e-6:  # layers meet at the band's lower edge: no part
        lo[2] -= (centre[2] + lo[2] - settings.band[0]) % pitch  # mixes points from under and in the band
    cell = np.floor((local - lo) / pitch).astype(np.int64)
    shape = tuple(int(v) for v in np.floor((half - lo) / pitch).astype(np.int64) + 2)
    flat = np.ravel_multi_index(cell.T, shape)
    weight = np.bincount(flat, weights=np.asarray(weights, dtype=np.float64), minlength=int(np.prod(shape)))
    occupied = (weight >= settings.min_weight).reshape(shape)
    if not occupied.any():
        return None
    closed = ndimage.binary_closing(occupied, structure=np.ones((3, 3, 3), bool)) | occupied
    in_layer = np.zeros((3, 3, 3), dtype=bool)
    in_layer[:, :, 1] = ndimage.generate_binary_structure(2, 1)  # what an outline encloses in its own layer
    solid = ndimage.binary_fill_holes(closed) | ndimage.binary_fill_holes(closed, structure=in_layer)
    z_layers = centre[2] + (lo[2] + (np.arange(shape[2]) + 0.5) * pitch) * axes[2, 2]
    wz = layer_weights(z_layers, settings.band)
    boxes = greedy_boxes(solid)
    if len(boxes) > settings.max_parts:
        outside = None if settings.band is None else band_outside(solid, wz)
        boxes = merge_boxes(boxes, settings.max_parts, wz, outside)
    label = np.full(shape, -1, dtype=np.int64)
    for b, (i0, j0, k0, i1, j1, k1) in enumerate(boxes):
        label[i0:i1, j0:j1, k0:k1] = b
    kept = solid.reshape(-1)[flat]  # points in voxels that the solid dropped (lone floaters) are left out
    local, cell, flat = local[kept], cell[kept], flat[kept]
    has_point = np.zeros(int(np.prod(shape)), dtype=bool)
    has_point[flat] = True
    enclosed = np.argwhere(solid & ~has_point.reshape(shape))  # [E, 3] solid voxels no point is in
    unit = np.argwhere(np.ones((2, 2, 2), dtype=bool)) * (1 - 2 * _CORNER_INSET) + _CORNER_INSET  # [8, 3]
    corners = lo + (enclosed[:, None, :] + unit[None]) * pitch  # [E, 8, 3]
    onto, onto_owner = _onto_shared_faces(local, cell, flat, solid, label, lo, pitch)
    extra = np.concatenate([corners.reshape(-1, 3), onto])
    of_points = _by_box(label.reshape(-1)[flat], len(boxes))
    of_extra = _by_box(np.concatenate([np.repeat(label[tuple(enclosed.T)], 8), onto_owner]), len(boxes))
    inner = np.concatenate([np.repeat((solid & ~closed)[tuple(enclosed.T)], 8),  # the filled inside's corners,
                            np.ones(len(onto), dtype=bool)])  # not a closed gap's; the points on shared faces
    across = None if cov is None else np.einsum("dj,njk,ek->nde", axes[:2], cov[kept], axes[:2])  # [n, 2, 2]
    everywhere = (local.min(axis=0), local.max(axis=0))
    parts = []
    for b in range(len(boxes)):
        points_in_box = local[of_points[b]]
        lo_b, hi_b = (points_in_box.min(axis=0), points_in_box.max(axis=0)) if len(points_in_box) else everywhere
        corners_b = extra[of_extra[b]]
        inside_b = inner[of_extra[b]][:, None]
        group = np.concatenate([points_in_box, np.where(inside_b, np.clip(corners_b, *everywhere),
                                                        np.clip(corners_b, lo_b, hi_b))])
        if across is not None and len(points_in_box):
            group = _as_wide_as_gaussians(group, points_in_box, across[of_points[b]], half)
        if len(group):
            part = hull_part(group)
            parts.append(trimesh.Trimesh(part.vertices @ axes + centre, part.faces, process=False))
    if not parts:
        return None
    return trimesh.util.concatenate(parts)


def _as_wide_as_gaussians(group: np.ndarray, points: np.ndarray, across: np.ndarray, half: np.ndarray) -> np.ndarray:
    """`group` (box frame) widened where it is narrower than its Gaussians (`points` [n, 3], their horizontal
    covariances `across` [n, 2, 2] in the box's axes; sigma [2]: their median standard deviation along each
    horizontal axis), its added points kept within the box's `half` extents.

    A plate, narrower than 2 sigma across one axis, gets copies of its points at its middle +- sigma across it.
    A post, narrower than 2 sigma.max() both ways, becomes a round post (`_post_ring`): a post's Gaussians lie on
    its surface, often all on the side the cameras saw, and a square as wide as they are around them (what it
    was) put half of it in the free space in front of them and reached past a 3 cm pole by a map cell."""
    sigma = np.median(np.sqrt(np.diagonal(across, axis1=1, axis2=2)), axis=0)
    span = group[:, :2].max(axis=0) - group[:, :2].min(axis=0)
    if (span < 2 * sigma.max()).all():
        return np.concatenate([group, _post_ring(group, points, across, float(sigma.max()), half)])
    out = [group]
    for d in range(2):
        lo_d, hi_d = group[:, d].min(), group[:, d].max()
        if hi_d - lo_d < 2 * sigma[d]:
            for side in (-1.0, 1.0):
                copy = group.copy()
                copy[:, d] = np.clip((lo_d + hi_d) / 2 + side * sigma[d], -half[d], half[d])
                out.append(copy)
    return np.concatenate(out)


def _by_box(owner: np.ndarray, boxes: int) -> list[np.ndarray]:
    """The indices of the rows that each box owns (`owner` [N], the box of each row), in row order: one sort,
    not a pass over every row for each box."""
    order = np.argsort(owner, kind="stable")
    cuts = np.searchsorted(owner[order], np.arange(boxes + 1))
    return [order[a:e] for a, e in zip(cuts[:-1], cuts[1:])]


def _post_ring(group: np.ndarray, points: np.ndarray, across: np.ndarray, sigma: float,
               half: np.ndarray) -> np.ndarray:
    """The corners (box frame) of a vertical 16-sided prism over `group`'s height around a disc: its middle the
    point nearest the box's middle, on the way there from the group's middle, within `sigma` of all of `group`,
    its radius the largest distance of a Gaussian's centre (`points`) from there plus that Gaussian's narrowest
    horizontal standard deviation (from `across`). The Gaussians are on the post's surface, the post behind them
    towards the object's middle (a lamp's pole is its box's middle; a chair's leg lies inwards of its outer face),
    and every Gaussian lies at least its own thickness inside it: a flat splat on a 3 cm pole adds 0.23 cm."""
    middle = _towards_middle((group[:, :2].min(axis=0) + group[:, :2].max(axis=0)) / 2, group[:, :2], sigma)
    thickness = np.sqrt(np.maximum(np.linalg.eigvalsh(across)[:, 0], 0.0))  # each Gaussian's narrowest sigma
    radius = float((np.linalg.norm(points[:, :2] - middle, axis=1) + thickness).max())
    turn = np.arange(_POST_SIDES) * 2 * math.pi / _POST_SIDES
    ring = middle + np.stack([np.cos(turn), np.sin(turn)], axis=1) * radius / math.cos(math.pi / _POST_SIDES)
    ring = np.clip(ring, -half[:2], half[:2])
    z = (group[:, 2].min(), group[:, 2].max())
    return np.array([[x, y, h] for x, y in ring for h in z])


def _towards_middle(start: np.ndarray, points: np.ndarray, reach: float) -> np.ndarray:
    """The point [2] nearest the box's middle (the origin) on the segment from `start` to it that lies within
    `reach` of every one of `points` [n, 2]; `start` itself where none does."""
    a, b = start - points, -start  # the point at t in [0, 1] is start + t b; |a + t b| <= reach for every point
    qa, qb, qc = b @ b, 2 * (a @ b), np.einsum("nd,nd->n", a, a) - reach**2
    if qa == 0.0:
        return start
    root = qb * qb - 4 * qa * qc
    if (root < 0).any():
        return start
    return start + float(np.clip(((-qb + np.sqrt(root)) / (2 * qa)).min(), 0.0, 1.0)) * b


def _onto_shared_faces(local: np.ndarray, cells: np.ndarray, flat: np.ndarray, solid: np.ndarray, label: np.ndarray,
                       lo: np.ndarray, pitch: float) -> tuple[np.ndarray, np.ndarray]:
    """Copies of the points (box frame, their voxels `cells`, flat indices `flat`) next to a face their box
    shares with another box's solid voxel, moved onto that face (a hair short of it), and their box: where a voxel
    boundary cuts through the material (a table top's two faces in two layers, a leg under the top, a pole's
    Gaussians in two columns) each side's hull then reaches the boundary, so the parts together are as thick as
    the Gaussians. Which voxels have such a face is found on the grid, then looked up for each point."""
    own = label.reshape(-1)[flat]
    out, owner = [], []
    for d in range(3):
        for step in (-1, 1):
            here, there = [slice(None)] * 3, [slice(None)] * 3
            here[d], there[d] = (slice(0, -1), slice(1, None)) if step > 0 else (slice(1, None), slice(0, -1))
            shared = np.zeros(solid.shape, dtype=bool)
            shared[tuple(here)] = solid[tuple(there)] & (label[tuple(there)] != label[tuple(here)])
            ok = shared.reshape(-1)[flat]
            moved = local[ok].copy()
            moved[:, d] = lo[d] + (cells[ok, d] + (step > 0)) * pitch - step * _CORNER_INSET * pitch
            out.append(moved)
            owner.append(own[ok])
    return np.concatenate(out), np.concatenate(owner)
