"""What a person walking a path can see: objects near it with no wall between (line of sight on the map).

The view is blocked by wall and closed-door cells: cells blocked in the occupancy grid that lie inside a
wall's or closed door's footprint, so a doorway (free in the grid) lets the view through even where a
wall's footprint spans it. An object counts as seen when, from some point of the path within `within_m`
of its footprint, the segment to the footprint's nearest point crosses no such cell.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import shapely
from shapely.geometry import LineString, Point
from shapely.ops import nearest_points

from sagebench.instructions.relations import PASSED_M, Layout, objects_passed

STEP_M = 0.25  # path points tested, metres apart
SEEN_BATCH = 256  # points whose sight `share_seen` tests at once (bounded memory)
FOOTPRINT_POINTS = 32  # points at most that stand for a footprint (`footprint_points`)


@dataclass(frozen=True)
class SightMap:
    walls: np.ndarray  # [H, W] bool, True where a wall or closed door blocks the view
    resolution: float  # metres per cell
    origin: tuple[float, float]  # world (x, y) of cell (0, 0)'s lower-left corner

    def clear(self, p: np.ndarray, q: np.ndarray) -> bool:
        """No wall cell on the segment p -> q ([2] world metres), its two end cells left out."""
        return bool(self.clear_all(np.asarray(p, dtype=np.float64)[None], np.asarray(q, dtype=np.float64)[None])[0])

    def clear_all(self, p: np.ndarray, q: np.ndarray) -> np.ndarray:
        """[N] bool: `clear` of each segment p[i] -> q[i] ([N, 2] world metres), all at once: each sampled every
        half cell from p to q, the points past its own end repeating the end."""
        n = np.maximum(np.ceil(np.hypot(*(q - p).T) / (self.resolution / 2)).astype(np.int64), 1)
        k = np.arange(int(n.max(initial=1)) + 1)
        t = np.where(k[None] >= n[:, None], 1.0, k[None] * (1.0 / n[:, None]))[..., None]  # as np.linspace's
        cells = np.floor((p[:, None] + t * (q - p)[:, None] - np.asarray(self.origin)) / self.resolution
                         ).astype(np.int64)
        end = (cells == cells[:, :1]).all(-1) | (cells == cells[:, -1:]).all(-1)
        h, w = self.walls.shape
        col, row = cells[..., 0], cells[..., 1]
        inside = (row >= 0) & (row < h) & (col >= 0) & (col < w)
        blocked = self.walls[row.clip(0, h - 1), col.clip(0, w - 1)] & inside & ~end
        return ~blocked.any(axis=1)

    def share_seen(self, p: np.ndarray, targets: np.ndarray) -> np.ndarray:
        """[K] the share of the `targets` [M, 2] that each point of p [K, 2] sees (world metres; `clear`)."""
        if not len(p):
            return np.zeros(0)
        m = len(targets)
        return np.concatenate([self.clear_all(np.repeat(c, m, axis=0), np.tile(targets, (len(c), 1))).reshape(-1, m)
                               .mean(axis=1) for c in np.array_split(p, -(-len(p) // SEEN_BATCH))])


def footprint_points(polygons: Sequence[shapely.Geometry], resolution: float,
                     origin: tuple[float, float]) -> np.ndarray:
    """[M, 2] points standing for a footprint (world metres), M <= FOOTPRINT_POINTS: the centres of the map cells
    inside it, evenly thinned out in row order; its representative point when no cell centre lies inside."""
    shape = shapely.union_all(list(polygons))
    x0, y0, x1, y1 = shape.bounds
    cols = np.arange(np.floor((x0 - origin[0]) / resolution), np.ceil((x1 - origin[0]) / resolution))
    rows = np.arange(np.floor((y0 - origin[1]) / resolution), np.ceil((y1 - origin[1]) / resolution))
    gx, gy = np.meshgrid(origin[0] + (cols + 0.5) * resolution, origin[1] + (rows + 0.5) * resolution)
    inside = np.column_stack([gx.ravel(), gy.ravel()])[shapely.contains_xy(shape, gx.ravel(), gy.ravel())]
    if not len(inside):
        return np.asarray(shape.representative_point().coords, dtype=np.float64)
    return inside[np.unique(np.linspace(0, len(inside) - 1, min(len(inside), FOOTPRINT_POINTS)).round().astype(int))]


def sight_map(occupancy: np.ndarray, resolution: float, origin: tuple[float, float],
              blockers: Sequence[shapely.Geometry]) -> SightMap:
    """occupancy [H, W] uint8 (1 blocked); blockers: footprints of walls and closed doors (world metres)."""
    h, w = occupancy.shape
    xs = origin[0] + (np.arange(w) + 0.5) * resolution
    ys = origin[1] + (np.arange(h) + 0.5) * resolution
    gx, gy = np.meshgrid(xs, ys)
    inside = np.zeros((h, w), dtype=bool)
    if blockers:
        inside = shapely.contains_xy(shapely.union_all(list(blockers)).buffer(resolution / 2), gx, gy)
    return SightMap(inside & (occupancy == 1), float(resolution), (float(origin[0]), float(origin[1])))


def objects_seen(lay: Layout, path_xy: np.ndarray, sight: SightMap | None, within_m: float = PASSED_M) -> list[int]:
    """Indices of the objects passed (relations.objects_passed) that some path point sees, in walking order.

    path_xy: [M, 2] world metres. Without a sight map every object passed counts.
    """
    passed = objects_passed(lay, path_xy, within_m)
    if sight is None or not passed:
        return passed
    line = LineString(path_xy)
    pts = shapely.get_coordinates(shapely.line_interpolate_point(line, np.append(np.arange(0, line.length, STEP_M),
                                                                                 line.length)))
    out = []
    for j in passed:
        geom = lay.geoms[j]
        near = pts[shapely.distance(geom, shapely.points(pts)) <= within_m]
        if len(near) == 0:  # the path comes close only between two sample points
            near = np.array([nearest_points(line, geom)[0].coords[0]])
        for p in near:
            q = np.asarray(nearest_points(Point(p), geom)[1].coords[0])
            if sight.clear(p, q):
                out.append(j)
                break
    return out
