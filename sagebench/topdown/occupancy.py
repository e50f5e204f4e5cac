"""Occupancy from the geometry inside the agent's height band, and inflation by the agent radius.

A cell is blocked by a part (a connected piece of a mesh) when
- a triangle of the part, clipped to the band [z_lo, z_hi], touches the cell seen from above (thin
  things: a 4 cm door leaf, a wall's side faces, a lamp's pole), or
- the vertical line through the cell centre meets the part at heights whose span [lowest, highest]
  overlaps the band (solid things: the inside of a wall, a cabinet's body under its top above the band).
A table top at 0.75 m therefore blocks at the default band (0.05..1.2 m), a lamp hanging from 1.8 m
does not, and a 1 cm rug does not. `scene_occupancy` is build-scene's step: the blocked and navigable maps of
a scene's objects on the map's grid.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from scipy import ndimage
from shapely.geometry.base import BaseGeometry

from sagebench.errors import ConfigError
from sagebench.topdown.raster import Grid, polygon_mask, touched_cells, triangle_centre_hits

if TYPE_CHECKING:
    from sagebench.scene.model import SceneObject
    from sagebench.topdown.footprints import Parts

NOT_BLOCKING_KINDS = frozenset({"floor", "ceiling"})  # walkable surfaces and what is above every head


@dataclass(frozen=True)
class Occupancy:
    """What blocks the agent on the map's grid, and where its centre may stand."""

    occupied: np.ndarray  # [H, W] bool, blocked: geometry in the band, or outside the floor plan
    navigable: np.ndarray  # [H, W] bool, free cells at least the agent's radius from every blocked one (`inflate`)
    band_polys: np.ndarray  # [M, 9, 2] float64 world m, the blocking triangles' outlines in the band (`clip_to_band`)
    blocking: frozenset[int]  # instance ids with some geometry in the band


def blockers(objects: Sequence[SceneObject]) -> list[SceneObject]:
    """The objects whose geometry may block, in order: all but floors and ceilings."""
    return [o for o in objects if o.kind not in NOT_BLOCKING_KINDS]


def scene_occupancy(objects: Sequence[SceneObject], parts: Mapping[int, Parts], plan: BaseGeometry, grid: Grid,
                    band: tuple[float, float], radius: float) -> Occupancy:
    """The `band_occupancy` of the `blockers` among `objects` (their `parts`: instance id -> `mesh_parts`, world m)
    in `band` (world z lo, hi, m), every cell outside the floor `plan` blocked too, inflated by the agent's
    `radius` (m). No navigable cell left is a ConfigError naming agent.radius."""
    objs = blockers(objects)
    tris, part, owner = _stack([parts[o.instance_id] for o in objs])
    occupied = band_occupancy(tris, part, grid, *band) | ~polygon_mask(plan, grid)
    navigable = inflate(occupied, radius, grid.resolution)
    if not navigable.any():
        raise ConfigError(f"an agent of radius {radius:g} m fits nowhere on the floor: no navigable cell "
                          "(a smaller agent radius, or a scene with free floor)", field="agent.radius")
    polys, src = clip_to_band(tris, *band)
    return Occupancy(occupied, navigable, polys, frozenset(objs[i].instance_id for i in np.unique(owner[src])))


def _stack(items: list[Parts]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Concatenate per-object (tris [F, 3, 3], part [F]) into tris, globally unique part ids, owner index."""
    if not items:
        return np.zeros((0, 3, 3)), np.zeros(0, np.int64), np.zeros(0, np.int64)
    offsets = np.cumsum([0] + [int(p.max()) + 1 if len(p) else 0 for _, p in items[:-1]])
    tris = np.concatenate([t for t, _ in items])
    part = np.concatenate([p + off for (_, p), off in zip(items, offsets)])
    owner = np.concatenate([np.full(len(t), i) for i, (t, _) in enumerate(items)])
    return tris, part, owner


def clip_to_band(tris: np.ndarray, z_lo: float, z_hi: float) -> tuple[np.ndarray, np.ndarray]:
    """The xy outline of each triangle's part inside z_lo <= z <= z_hi.

    tris: [N, 3, 3] float, m. Returns polys [M, 9, 2] (convex, vertices in cyclic order, padded by
    repeating a vertex) and source [M] int64, the triangle each came from; triangles wholly outside
    the band are dropped. A clipped triangle's corners are its vertices inside the band and the points
    where its edges cross z_lo and z_hi, so at most 9 candidates.
    """
    a = tris
    b = np.roll(tris, -1, axis=1)  # edge k runs from vertex k to vertex k + 1
    z = tris[..., 2]
    cands = [tris]
    valid = [(z >= z_lo) & (z <= z_hi)]
    for plane in (z_lo, z_hi):
        da, db = a[..., 2] - plane, b[..., 2] - plane
        cross = da * db < 0
        t = np.where(cross, da / np.where(cross, da - db, 1.0), 0.0)
        cands.append(a + t[..., None] * (b - a))
        valid.append(cross)
    pts = np.concatenate(cands, axis=1)[..., :2]  # [N, 9, 2]
    ok = np.concatenate(valid, axis=1)  # [N, 9]
    keep = ok.any(axis=1)
    pts, ok = pts[keep], ok[keep]
    first = pts[np.arange(len(pts)), ok.argmax(axis=1)]  # [M, 2] a valid corner, pads the invalid slots
    pts = np.where(ok[..., None], pts, first[:, None, :])
    centre = (pts * ok[..., None]).sum(axis=1) / ok.sum(axis=1, keepdims=True)
    angle = np.arctan2(pts[..., 1] - centre[:, None, 1], pts[..., 0] - centre[:, None, 0])
    order = np.argsort(angle, axis=1, kind="stable")
    return np.take_along_axis(pts, order[..., None], axis=1), np.nonzero(keep)[0]


def band_occupancy(tris: np.ndarray, part: np.ndarray, grid: Grid, z_lo: float, z_hi: float) -> np.ndarray:
    """[H, W] bool, cells blocked by geometry in the band (see the module docstring).

    tris: [N, 3, 3] float world m, the triangles of every blocking mesh; part: [N] int, the connected
    part each triangle belongs to (parts are what the solid test spans).
    """
    h, w = grid.shape
    out = np.zeros(h * w, dtype=bool)
    polys, _ = clip_to_band(tris, z_lo, z_hi)
    rows, cols = touched_cells(polys, grid)
    out[rows * w + cols] = True
    out |= _solid_spans(tris, part, grid, z_lo, z_hi)
    return out.reshape(h, w)


def _solid_spans(tris: np.ndarray, part: np.ndarray, grid: Grid, z_lo: float, z_hi: float) -> np.ndarray:
    """[H * W] bool: cells where some part's [lowest, highest] surface over the centre overlaps the band."""
    h, w = grid.shape
    out = np.zeros(h * w, dtype=bool)
    z = tris[..., 2]
    # a part wholly above or below the band cannot span it
    _, inv = np.unique(part, return_inverse=True)
    pmin = np.full(inv.max() + 1 if len(inv) else 0, np.inf)
    pmax = np.full_like(pmin, -np.inf)
    np.minimum.at(pmin, inv, z.min(axis=1))
    np.maximum.at(pmax, inv, z.max(axis=1))
    near = ((pmax >= z_lo) & (pmin <= z_hi))[inv]
    tris, inv = tris[near], inv[near]
    j, rows, cols, zs = triangle_centre_hits(tris, grid)
    if len(j) == 0:
        return out
    key = inv[j] * (h * w) + rows * w + cols
    uniq, k = np.unique(key, return_inverse=True)
    lo = np.full(len(uniq), np.inf)
    hi = np.full(len(uniq), -np.inf)
    np.minimum.at(lo, k, zs)
    np.maximum.at(hi, k, zs)
    spans = (hi >= z_lo) & (lo <= z_hi)
    out[uniq[spans] % (h * w)] = True
    return out


def _square_distance(dr: np.ndarray, dc: np.ndarray) -> np.ndarray:
    """Distance, in cells, from a cell's centre to the nearest point of the cell (dr, dc) away."""
    return np.hypot(np.maximum(np.abs(dr) - 0.5, 0.0), np.maximum(np.abs(dc) - 0.5, 0.0))


def inflate(occupancy: np.ndarray, radius: float, resolution: float) -> np.ndarray:
    """[H, W] bool navigable: free cells whose centre is at least `radius` m from every blocked cell.

    A cell is blocked when geometry touches any part of it, so the distance is measured to the blocked
    cell's square, not its centre: a robot centred on a navigable cell never reaches into a blocked
    cell. occupancy: [H, W] bool or uint8, nonzero = blocked. The grid's border is not treated as
    blocked, so callers keep a blocked margin (outside the floor plan).
    """
    blocked = occupancy != 0
    if not blocked.any():
        return ~blocked
    widest = float(ndimage.distance_transform_edt(~blocked).max()) * resolution  # a free centre to a blocked centre
    if widest < radius - 1e-9:  # every free cell is that close to a blocked square: none left, and no disc to build
        return np.zeros_like(blocked)
    reach = int(np.ceil(radius / resolution + 0.5))
    dr, dc = np.mgrid[-reach : reach + 1, -reach : reach + 1]
    disk = _square_distance(dr, dc) * resolution < radius - 1e-9
    return ~ndimage.binary_dilation(blocked, structure=disk)


def inflate_reference(occupancy: np.ndarray, radius: float, resolution: float) -> np.ndarray:
    """Plain version of `inflate`: each free cell against every blocked cell's square."""
    blocked = np.argwhere(occupancy != 0)
    out = np.zeros(occupancy.shape, dtype=bool)
    for r, c in np.argwhere(occupancy == 0):
        if not len(blocked):
            out[r, c] = True
            continue
        d = _square_distance(blocked[:, 0] - r, blocked[:, 1] - c) * resolution
        out[r, c] = bool(d.min() >= radius - 1e-9)
    return out
