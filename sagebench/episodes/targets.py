"""What a scene's trajectories start and end at, and how instructions name it: the uniquely named objects,
doors and rooms of a built scene (leaving out unreachable rooms), with the context instructions are written in."""

from __future__ import annotations

import numpy as np
from shapely.geometry import Polygon

from sagebench.astar.sampling import GridMap, TargetSpec
from sagebench.instructions.base import SceneContext, make_context
from sagebench.instructions.naming import ObjectInfo, RoomInfo
from sagebench.instructions.sight import SightMap, sight_map
from sagebench.scene.model import UNLABELLED, SceneSpec
from sagebench.topdown.grid_file import TopdownGrids
from sagebench.topdown.semantic_map import SemanticMap

TARGET_KINDS = ("object", "door")  # what a trajectory may start or end at, besides rooms
FIXTURE_KINDS = ("window",)  # what else an instruction may mention


def scene_context(spec: SceneSpec, smap: SemanticMap, type_mix: dict[str, float] | None = None) -> SceneContext:
    """Objects, rooms, unique names (relations allowed) and footprints of one scene, for naming and instructions.

    Objects and doors are what trajectories start and end at; an object's attributes are its scene.json
    attributes plus its door state. Footprints of things above the agent's band (ceiling lamps) are left
    out, so they serve as no landmark.
    """
    attrs = {o.instance_id: dict(o.attributes) for o in spec.objects}
    top = smap.band_m[1]  # world z, the floor included

    def info(i) -> ObjectInfo:
        return ObjectInfo(i.instance_id, i.category, i.room,
                          {**attrs.get(i.instance_id, {}), **({"state": i.door_state} if i.door_state else {})})

    named = [i for i in smap.instances if i.category != UNLABELLED]  # an unlabelled obstacle has no name to give
    objects = [info(i) for i in named if i.kind in TARGET_KINDS]
    fixtures = [info(i) for i in named if i.kind in FIXTURE_KINDS]
    footprints = {i.instance_id: [np.asarray(p[0], dtype=np.float64) for p in i.polygon.coordinates]
                  for i in named if i.kind in TARGET_KINDS and i.min_z <= top and i.polygon.coordinates}
    return make_context(objects, [RoomInfo(r.id, r.type) for r in spec.rooms],
                        {r.id: np.asarray(r.polygon, dtype=np.float64) for r in spec.rooms}, footprints,
                        fixtures=fixtures, doors={i.instance_id for i in smap.instances if i.kind == "door"},
                        type_mix=type_mix)


def scene_sight(smap: SemanticMap, grid: GridMap | TopdownGrids, occupancy: np.ndarray) -> SightMap:
    """The cells that block the view: blocked cells inside a wall's or a closed door's footprint (`grid`: its
    resolution and origin)."""
    blockers = [Polygon(p[0], p[1:]) for i in smap.instances
                if i.kind == "wall" or (i.kind == "door" and i.door_state == "closed") for p in i.polygon.coordinates]
    return sight_map(occupancy, grid.resolution, grid.origin, blockers)


def scene_targets(spec: SceneSpec, smap: SemanticMap,
                  ctx: SceneContext | None = None) -> tuple[list[TargetSpec], dict[str, str]]:
    """Targets that can be named uniquely, and target key -> referring expression.

    Objects and doors standing in the agent's height band (not ceiling lamps) and rooms, except unreachable
    rooms and what is in them (`unreachable_rooms`).
    """
    ctx = scene_context(spec, smap) if ctx is None else ctx
    top = smap.band_m[1]  # world z, the floor included
    cut_off = set(unreachable_rooms(smap))
    targets: list[TargetSpec] = []
    names: dict[str, str] = {}
    for inst in smap.instances:
        if (inst.kind not in TARGET_KINDS or inst.instance_id not in ctx.names or inst.min_z > top
                or not inst.polygon.coordinates or inst.room in cut_off):
            continue
        key = f"object:{inst.instance_id}"
        outlines = tuple(np.asarray(poly[0], dtype=np.float64) for poly in inst.polygon.coordinates)
        targets.append(TargetSpec(key, "object", inst.instance_id, inst.room, outlines))
        names[key] = ctx.names[inst.instance_id]
    for room in spec.rooms:
        if room.id in ctx.room_names and room.id not in cut_off:
            key = f"room:{room.id}"
            targets.append(TargetSpec(key, "room", None, room.id, (np.asarray(room.polygon, dtype=np.float64),)))
            names[key] = ctx.room_names[room.id]
    return targets, names


def unreachable_rooms(smap: SemanticMap) -> tuple[str, ...]:
    """Rooms build-scene found unreachable (most of their navigable floor outside the main region)."""
    return tuple(r.room_id for r in smap.rooms if not r.reachable)
