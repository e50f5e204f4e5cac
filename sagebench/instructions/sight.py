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


@dataclass(frozen=True)
class SightMap:
    walls: np.ndarray  # [H, W] bool, True where a wall or closed door blocks the view
    resolution: float  # metres per cell
    origin: tuple[float, float]  # world (x, y) of cell (0, 0)'s lower-left corner

    def clear(self, p: np.ndarray, q: np.ndarray) -> bool:
        """No wall cell on the segment p -> q ([2] world metres), its two end cells left out."""
        n = max(int(np.ceil(np.hypot(*(q - p)) / (self.resolution / 2))), 1)
        t = np.linspace(0.0, 1.0, n + 1)[:, None]
        cells = np.floor((p + t * (q - p) - np.asarray(self.origin)) / self.resolution).astype(np.int64)
        end = {tuple(cells[0]), tuple(cells[-1])}
        h, w = self.walls.shape
        for col, row in cells:
            if (col, row) in end or not (0 <= row < h and 0 <= col < w):
                continue
            if self.walls[row, col]:
                return False
        return True


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
