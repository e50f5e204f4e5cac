"""What the Gaussians and occupancy.png show beyond the labels: stray Gaussians dropped, geometry no label explains
made an obstacle.

- Floaters: a Gaussian is a floater when the 3 x 3 x 3 block of `floater_cell` cells around its own holds at most
  `floater_neighbours` other Gaussians. On the synth apartments (0.05 m, 2) this drops 3 in 4 of Gaussians
  scattered at random over the scene and under 1 in 1,000 of those on its surfaces; a floater within a cell of a
  surface cannot be told from it and stays. Floaters are dropped from the geometry (gaussians.ply keeps them,
  as background).
- Unlabelled obstacles, on occupancy.png's grid over the rooms: a cell is evidence when occupancy.png marks it
  occupied by an object (0) or when the background Gaussians (in no label's box, on no structure) over it in the
  agent's band sum to `min_opacity`. Evidence that the imported geometry does not block, opened by one cell (a rim
  left by rasterising a little differently goes), in pieces of `unlabelled_min_area` or more, becomes an obstacle:
  a box per rectangle of its cells, from the floor to the top of the background Gaussians over it (to the band's
  top where it has none).
- Surface noise: how far the Gaussians on walls and floor scatter about their planes, a capture's positional noise
  that widens every obstacle and blurs every wall by about as much. Over the Gaussians in no label's box (grown by
  `box_margin`): those within `reach` of a wall piece's face (away from its ends, bottom and top by `reach`, and
  from its ends by half its thickness more: a corner's other wall, an opening's reveal) and those within `reach` of
  the floor (z = 0) over the rooms, away from the walls. Each face's and the floor's distances are taken about
  their median (structure.json a little off the capture is an offset, not noise); the noise is 1.4826 times the
  median absolute distance (the standard deviation of normal noise). On the demo folder it reads 0 clean and
  0.22, 0.54, 1.05, 2.0 cm for 2 mm, 5 mm, 1 cm, 2 cm of normal jitter per axis; wider noise than about half
  `reach` reads low (2.7 cm for 3 cm).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import shapely
import trimesh
from scipy import ndimage

from sagebench.collider_export.voxel import greedy_boxes
from sagebench.importers.boxes import OrientedBox, box_owner
from sagebench.importers.interiorgs_files import OccupancyMap
from sagebench.topdown.raster import Grid, polygon_mask

OBJECT = 0  # occupancy.png's value for a cell an object stands on
_INSET = 1e-3  # each box is pulled in by this (m), so that boxes sharing an edge stay separate convex parts


def floaters(means: np.ndarray, cell: float, neighbours: int) -> np.ndarray:
    """[N] whether each Gaussian is a floater (module docstring). Counted per occupied cell, not per Gaussian: only
    the cells holding no more than `neighbours` + 1 are looked at further (any other Gaussian has that many
    neighbours in its own cell), and a neighbouring cell's key is the cell's own plus a fixed step."""
    c = np.floor(np.asarray(means, dtype=np.float64) / cell).astype(np.int64)
    c -= c.min(axis=0) - 1  # one empty cell of margin below, so every neighbour index is >= 0
    dims = c.max(axis=0) + 2
    cells, inverse, count = np.unique(np.ravel_multi_index(c.T, dims), return_inverse=True, return_counts=True)
    few = np.flatnonzero(count <= neighbours + 1)
    near = np.zeros(len(few), dtype=np.int64)
    for step in (np.argwhere(np.ones((3, 3, 3), dtype=bool)) - 1) @ np.array([dims[1] * dims[2], dims[2], 1]):
        k = cells[few] + step
        at = np.minimum(np.searchsorted(cells, k), len(cells) - 1)
        near += np.where(cells[at] == k, count[at], 0)
    lonely = np.zeros(len(cells), dtype=bool)
    lonely[few[near - 1 <= neighbours]] = True
    return lonely[inverse]


MAD_TO_SD = 1.4826  # the median absolute deviation of normal noise times this is its standard deviation
MIN_FACE_POINTS = 20  # a face (or the floor) with fewer Gaussians is left out: their median would take their noise


def surface_noise(means: np.ndarray, walls: list[OrientedBox], floor: shapely.Geometry, boxes: list[OrientedBox],
                  margin: float, reach: float) -> float | None:
    """The Gaussians' (centres [N, 3], floaters aside) noise about the wall pieces' faces and the floor `floor`
    (the rooms' union), m (module docstring); None where no face or floor holds MIN_FACE_POINTS of them."""
    pts = np.asarray(means, dtype=np.float64)
    pts = pts[box_owner(pts, boxes, margin) < 0]
    faces = [OrientedBox(b.centre, b.axes, b.half + [-b.half[1] - reach, reach, -reach]) for b in walls]
    usable = [k for k, f in enumerate(faces) if (f.half > 0).all()]
    owner = box_owner(pts, [faces[k] for k in usable])
    spread = []
    for k in np.unique(owner[owner >= 0]):
        wall = walls[usable[k]]
        across = wall.local(pts[owner == k])[:, 1]
        spread += [np.abs(across[np.sign(across) == side]) - wall.half[1] for side in (-1, 1)]
    off_walls = box_owner(pts, [OrientedBox(b.centre, b.axes, b.half + reach) for b in walls]) < 0
    low = np.flatnonzero(off_walls & (np.abs(pts[:, 2]) <= reach))
    spread.append(pts[low[shapely.contains_xy(floor, pts[low, 0], pts[low, 1])], 2])
    about = [d - np.median(d) for d in spread if len(d) >= MIN_FACE_POINTS]
    return MAD_TO_SD * float(np.median(np.abs(np.concatenate(about)))) if about else None


@dataclass(frozen=True)
class Unlabelled:
    """The obstacles no label explains: one mesh (world m) and area (m^2) each, and which of them covers each cell
    of occupancy.png's grid (0 none, k the k-th)."""

    meshes: list[trimesh.Trimesh]
    areas: list[float]
    cells: np.ndarray  # [H, W] int
    tops: list[float]  # m, each obstacle's top


def unlabelled_obstacles(shipped: OccupancyMap, blocked: np.ndarray, rooms: list[shapely.Polygon],
                         background: np.ndarray, alpha: np.ndarray, band: tuple[float, float], min_opacity: float,
                         min_area: float) -> Unlabelled:
    """The obstacles (module docstring) given the cells the imported geometry blocks [H, W] and the background
    Gaussians' centres [N, 3] and opacities [N]."""
    grid = Grid(shipped.origin, shipped.scale, shipped.values.shape)
    inside = polygon_mask(shapely.union_all(rooms), grid)
    i, j, ok = _cells(grid, background)
    in_band = ok & (background[:, 2] >= band[0]) & (background[:, 2] <= band[1])
    weight = np.zeros(grid.shape)
    np.add.at(weight, (i[in_band], j[in_band]), alpha[in_band])
    evidence = ((shipped.values == OBJECT) | (weight >= min_opacity)) & inside & ~blocked
    evidence = ndimage.binary_opening(evidence, structure=np.ones((3, 3), dtype=bool))
    pieces, n = ndimage.label(evidence)
    area = np.bincount(pieces.ravel(), minlength=n + 1) * grid.cell_area()
    keep = np.flatnonzero(area[1:] >= min_area - 1e-9) + 1
    cells = np.zeros(grid.shape, dtype=np.int64)
    meshes, tops = [], []
    for k, piece in enumerate(keep, start=1):
        mine = pieces == piece
        cells[mine] = k
        over = ok & (background[:, 2] >= band[0])
        over[over] = mine[i[over], j[over]]
        top = float(np.percentile(background[over, 2], 95)) if over.any() else band[1]
        tops.append(max(top, band[0] + grid.resolution))
        meshes.append(_prism(mine, grid, tops[-1]))
    return Unlabelled(meshes, [float(area[p]) for p in keep], cells, tops)


def _cells(grid: Grid, points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Row, column and whether on the grid, of each point."""
    j = np.floor((points[:, 0] - grid.origin[0]) / grid.resolution).astype(np.int64)
    i = np.floor((points[:, 1] - grid.origin[1]) / grid.resolution).astype(np.int64)
    ok = (i >= 0) & (i < grid.shape[0]) & (j >= 0) & (j < grid.shape[1])
    return np.where(ok, i, 0), np.where(ok, j, 0), ok


def _prism(cells: np.ndarray, grid: Grid, top: float) -> trimesh.Trimesh:
    """A box over each rectangle of `cells` [H, W], from the floor to `top`."""
    boxes = []
    for i0, j0, _, i1, j1, _ in greedy_boxes(cells[:, :, None]):
        lo = np.array([grid.origin[0] + j0 * grid.resolution, grid.origin[1] + i0 * grid.resolution, 0.0]) + _INSET
        hi = np.array([grid.origin[0] + j1 * grid.resolution, grid.origin[1] + i1 * grid.resolution, top]) - _INSET
        boxes.append(trimesh.creation.box(bounds=np.stack([lo, hi])))
    return trimesh.util.concatenate(boxes)
