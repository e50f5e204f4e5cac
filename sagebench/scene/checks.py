"""Plausibility of a loaded scene: refuses geometry no building has, before any map is computed.

A scene that parses can still be meaningless: metres authored with `units: "cm"` (a 13 cm apartment), a
floor a kilometre above the furniture, a hinge across the room from its door, a room of zero area. Each
check raises one SceneError naming scene.json and the field to fix; the limits are stated here once.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from sagebench.errors import SceneError
from sagebench.scene.model import Door, Room, SceneSpec

MIN_EXTENT_M = 1.0  # the scene's widest horizontal side must be at least this ...
MAX_EXTENT_M = 1000.0  # ... and at most this, in metres after units
FLOOR_TOLERANCE_M = 1.0  # the floor may lie this far outside the geometry's height range
HINGE_TOLERANCE_M = 0.5  # a door's hinge axis lies within this of its closed leaf's footprint box
OUTSIDE_ROOMS_M = 5.0  # an object's footprint box lies within this of some room polygon
MIN_ROOM_AREA_M2 = 0.01  # a room polygon encloses at least this floor area
NO_FLOOR = "no rooms and no floor meshes: cannot tell where the floor is"


def check_world_bounds(bounds: dict[int, np.ndarray], spec: SceneSpec, units: str, spec_path: Path) -> None:
    """Extent and floor of a normalised scene; `bounds` maps instance id -> [2, 3] world box (m, Z up)."""
    for i, obj in enumerate(spec.objects):
        if not np.isfinite(bounds[obj.instance_id]).all():
            raise SceneError("the transform takes the mesh to non-finite coordinates", path=spec_path,
                             field=f"objects[{i}].transform")
    boxes = np.stack(list(bounds.values()))
    lo, hi = boxes[:, 0].min(axis=0), boxes[:, 1].max(axis=0)
    wide = float(max(hi[0] - lo[0], hi[1] - lo[1]))
    if not MIN_EXTENT_M <= wide <= MAX_EXTENT_M:
        raise SceneError(
            f"the scene is {hi[0] - lo[0]:.3g} m x {hi[1] - lo[1]:.3g} m with units {units!r}; a building is "
            f"{MIN_EXTENT_M:g} to {MAX_EXTENT_M:g} m across (are the numbers in another unit?)",
            path=spec_path, field="units")
    floor = spec.floor_height
    if not lo[2] - FLOOR_TOLERANCE_M <= floor <= hi[2] + FLOOR_TOLERANCE_M:
        raise SceneError(
            f"the floor at {floor:.3g} m is more than {FLOOR_TOLERANCE_M:g} m outside the geometry's heights "
            f"({lo[2]:.3g}..{hi[2]:.3g} m)", path=spec_path, field="floor_height")


def check_rooms(rooms: list[Room], spec_path: Path) -> None:
    """Each normalised floor polygon ([x, y], m) is simple and encloses some area."""
    import shapely  # here, not at the top: refusing a bad scene.json imports no geometry library

    for j, room in enumerate(rooms):
        poly = shapely.Polygon(room.polygon)
        if not shapely.is_valid(poly):
            raise SceneError(f"the floor outline is not a simple polygon ({shapely.is_valid_reason(poly)})",
                             path=spec_path, field=f"rooms[{j}].polygon")
        if poly.area < MIN_ROOM_AREA_M2:
            raise SceneError(f"the floor outline encloses {poly.area:.3g} m^2 (at least {MIN_ROOM_AREA_M2:g} m^2)",
                             path=spec_path, field=f"rooms[{j}].polygon")


def check_floor_known(spec: SceneSpec, floor_triangles: list[np.ndarray], spec_path: Path) -> None:
    """Without rooms the floor meshes are the plan (topdown.builder.floor_plan): seen from above their triangles
    must cover at least a room's MIN_ROOM_AREA_M2 (a floor mesh seen edge-on covers none).
    floor_triangles: [F, 3, 3] world triangles (m) of each floor-kind object."""
    if spec.rooms:
        return
    area = 0.0
    for tri in floor_triangles:
        u, v = tri[:, 1, :2] - tri[:, 0, :2], tri[:, 2, :2] - tri[:, 0, :2]
        area += 0.5 * float(np.abs(u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0]).sum())
    if not area >= MIN_ROOM_AREA_M2:
        raise SceneError(NO_FLOOR, path=spec_path, field="rooms")


def check_hinge(door: Door, closed_bounds: np.ndarray, spec_path: Path, field: str) -> None:
    """The hinge (world, m) lies on or near its closed leaf's horizontal box `closed_bounds` [2, 3]."""
    gap = _box_distance(np.asarray(door.hinge[:2]), closed_bounds[:, :2])
    if gap > HINGE_TOLERANCE_M:
        raise SceneError(f"the hinge is {gap:.3g} m from its door leaf (at most {HINGE_TOLERANCE_M:g} m)",
                         path=spec_path, field=field)


def check_inside_rooms(spec: SceneSpec, bounds: dict[int, np.ndarray], spec_path: Path) -> None:
    """Every object's footprint box (world, m) lies within OUTSIDE_ROOMS_M of some room (scenes with rooms)."""
    if not spec.rooms:
        return
    import shapely

    area = shapely.union_all([shapely.Polygon(r.polygon) for r in spec.rooms])
    for i, obj in enumerate(spec.objects):
        (x0, y0, _), (x1, y1, _) = bounds[obj.instance_id]
        gap = float(shapely.distance(area, shapely.box(x0, y0, x1, y1)))
        if gap > OUTSIDE_ROOMS_M:
            raise SceneError(f"the object is {gap:.3g} m outside every room (at most {OUTSIDE_ROOMS_M:g} m)",
                             path=spec_path, field=f"objects[{i}].transform")


def _box_distance(p: np.ndarray, box: np.ndarray) -> float:
    """Distance from point p [2] to the axis-aligned box [[x0, y0], [x1, y1]]."""
    return float(np.linalg.norm(np.maximum(0.0, np.maximum(box[0] - p, p - box[1]))))
