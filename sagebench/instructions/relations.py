"""Spatial relations between objects, from their semantic-map footprints (world metres, XY plane).

next to: footprints closer than NEXT_TO_M. between: the object's centre lies near the segment joining
two others' centres, strictly inside it. nearest: the closest of a set to a landmark, by a clear margin.
left/right as seen from a point: the sign of the turn from the landmark's bearing to the object's.
A door joins the rooms whose floor lies within JOINS_M of its footprint (both sides of its wall).
Rooms passed and objects passed along a path are what a person walking it would notice.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import shapely
from shapely.geometry import LineString, Polygon

NEXT_TO_M = 0.6  # footprints this close (or touching) are "next to" each other
NEAREST_MARGIN_M = 0.5  # "the X nearest the L" needs the runner-up this much farther from L
BETWEEN_MAX_GAP_M = 1.5  # "between A and B": the object is this close to both
BETWEEN_OFFSET = 0.3  # ... and its centre within this fraction of |AB| of the segment (at least 0.4 m)
SIDE_MIN_DEG = 10.0  # left/right needs this much angle between the two bearings
PASSED_M = 1.0  # objects within this of a path are "passed"
JOINS_M = 0.3  # a door joins the rooms whose floor comes this close to its footprint (a wall is thinner)


@dataclass(frozen=True)
class Layout:
    """Footprints of a scene's objects as arrays: centres and pairwise gaps, indexed by position."""

    ids: tuple[int, ...]  # instance ids, in input order
    centroids: np.ndarray  # [N, 2] float64, world metres
    gaps: np.ndarray  # [N, N] float64, shortest distance between footprints, m (0 = touching); diagonal inf
    geoms: tuple[shapely.Geometry, ...]  # footprint per object
    positions: Mapping[int, int]  # instance id -> index

    def index(self, instance_id: int) -> int:
        return self.positions[instance_id]

    def __contains__(self, instance_id: object) -> bool:
        return instance_id in self.positions


def layout(footprints: Mapping[int, Sequence[np.ndarray]]) -> Layout:
    """Layout of `footprints`: instance id -> exterior rings, each [K, 2] float64 world metres."""
    ids = tuple(footprints)
    # make_valid: a real mesh's footprint ring can touch itself (GEOS then refuses the union)
    geoms = tuple(shapely.union_all([shapely.make_valid(Polygon(r)) for r in footprints[i] if len(r) >= 3]) for i in ids)
    arr = np.array(geoms, dtype=object)
    gaps = shapely.distance(arr[:, None], arr[None, :]) if ids else np.zeros((0, 0))
    gaps = np.asarray(gaps, dtype=np.float64)
    np.fill_diagonal(gaps, np.inf)
    cents = np.array([[g.centroid.x, g.centroid.y] if not g.is_empty else [np.nan, np.nan] for g in geoms],
                     dtype=np.float64).reshape(-1, 2)
    return Layout(ids, cents, gaps, geoms, {i: k for k, i in enumerate(ids)})


def next_to(lay: Layout, i: int) -> list[int]:
    """Indices of the objects next to object `i`, closest first."""
    near = np.nonzero(lay.gaps[i] <= NEXT_TO_M)[0]
    return [int(j) for j in near[np.argsort(lay.gaps[i, near], kind="stable")]]


def nearest(lay: Layout, candidates: Sequence[int], landmark: int) -> int | None:
    """The candidate closest to `landmark`, or None when the runner-up is within NEAREST_MARGIN_M of it."""
    cands = [c for c in candidates if c != landmark]
    if not cands:
        return None
    d = lay.gaps[landmark, cands]
    order = np.argsort(d, kind="stable")
    if len(cands) > 1 and d[order[1]] - d[order[0]] < NEAREST_MARGIN_M:
        return None
    return cands[int(order[0])]


def between(lay: Layout, i: int, a: int, b: int) -> bool:
    """Object `i` stands between `a` and `b`: close to both, its centre near the inside of segment a-b."""
    if len({i, a, b}) < 3 or max(lay.gaps[i, a], lay.gaps[i, b]) > BETWEEN_MAX_GAP_M:
        return False
    pa, pb, p = lay.centroids[a], lay.centroids[b], lay.centroids[i]
    ab = pb - pa
    length = float(np.hypot(*ab))
    if length == 0:
        return False
    t = float(np.dot(p - pa, ab)) / length**2
    offset = abs(float(ab[0] * (p - pa)[1] - ab[1] * (p - pa)[0])) / length
    return 0.15 < t < 0.85 and offset <= max(0.4, BETWEEN_OFFSET * length)


def rooms_joined(footprint: shapely.Geometry, floors: Mapping[str, shapely.Geometry]) -> tuple[str, ...]:
    """Ids of the rooms whose floor lies within JOINS_M of a door's footprint, in `floors`' order."""
    return tuple(rid for rid, floor in floors.items() if float(shapely.distance(footprint, floor)) <= JOINS_M)


def side_as_seen(viewer: np.ndarray, landmark: np.ndarray, point: np.ndarray) -> str | None:
    """"left" or "right": where `point` lies relative to `landmark` for someone at `viewer` facing the landmark.

    All [2] world metres. None when the two bearings are within SIDE_MIN_DEG of each other.
    """
    u, v = landmark - viewer, point - viewer
    turn = math.degrees(math.atan2(u[0] * v[1] - u[1] * v[0], u[0] * v[0] + u[1] * v[1]))
    if abs(turn) < SIDE_MIN_DEG or abs(turn) > 90:
        return None
    return "left" if turn > 0 else "right"


def rooms_along(path_xy: np.ndarray, rooms: Mapping[str, np.ndarray], step_m: float = 0.25) -> list[str]:
    """Room ids a path walks through, in order, each once per visit.

    path_xy: [M, 2] world metres; rooms: id -> floor polygon [K, 2]. Points in no room are skipped.
    """
    pts = _resample(path_xy, step_m)
    polys = [(rid, Polygon(poly)) for rid, poly in rooms.items()]
    out: list[str] = []
    inside = {rid: shapely.contains_xy(poly, pts[:, 0], pts[:, 1]) for rid, poly in polys}
    for k in range(len(pts)):
        here = next((rid for rid, _ in polys if inside[rid][k]), None)
        if here is not None and (not out or out[-1] != here):
            out.append(here)
    return out


def objects_passed(lay: Layout, path_xy: np.ndarray, within_m: float = PASSED_M) -> list[int]:
    """Indices of objects whose footprint comes within `within_m` of the path [M, 2], in walking order."""
    if len(path_xy) < 2 or not lay.ids:
        return []
    line = LineString(path_xy)
    arr = np.array(lay.geoms, dtype=object)
    close = np.nonzero(shapely.distance(arr, line) <= within_m)[0]
    along = [line.project(shapely.Point(lay.centroids[j])) for j in close]
    return [int(close[k]) for k in np.argsort(along, kind="stable")]


def _resample(path_xy: np.ndarray, step_m: float) -> np.ndarray:
    """[K, 2] points every `step_m` along the polyline [M, 2], both ends included."""
    seg = np.diff(path_xy, axis=0)
    s = np.concatenate([[0.0], np.cumsum(np.hypot(seg[:, 0], seg[:, 1]))])
    if s[-1] == 0:
        return path_xy[:1].astype(np.float64)
    t = np.append(np.arange(0.0, s[-1], step_m), s[-1])
    return np.column_stack([np.interp(t, s, path_xy[:, 0]), np.interp(t, s, path_xy[:, 1])])
