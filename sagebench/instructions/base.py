"""The instruction record every generator returns, and what a generator may know about a trajectory."""

from __future__ import annotations

from collections.abc import Callable, Collection, Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any, Literal

import numpy as np
from shapely.geometry import Polygon

from sagebench.instructions.execution import BlockedMap
from sagebench.instructions.naming import ObjectInfo, RoomInfo, object_names, room_names
from sagebench.instructions.relations import Layout, layout, rooms_joined
from sagebench.instructions.sight import SightMap
from sagebench.settings.gen_trajectories import HIGH_LEVEL_TYPES

Level = Literal["high", "low"]


@dataclass(frozen=True)
class Instruction:
    level: Level
    type: str  # Base_Action, Single_Goal, Add_Object, ...
    text: str
    source: str  # "template" or "llm:<model>"


@dataclass(frozen=True)
class SceneContext:
    """What high-level generators know about one scene: its objects, rooms, unique names and footprints.

    Ids are for lookups only; generated text uses `names` and `room_names`.
    """

    objects: tuple[ObjectInfo, ...]  # targets' kinds (objects, doors): what naming and templates use
    fixtures: tuple[ObjectInfo, ...]  # other things an answer may mention (windows)
    rooms: tuple[RoomInfo, ...]
    room_polygons: Mapping[str, np.ndarray]  # room id -> floor polygon [K, 2], world metres
    names: Mapping[int, str]  # instance id -> unique name in the scene
    room_names: Mapping[str, str]  # room id -> unique name
    local_names: Mapping[str, Mapping[int, str]]  # room id -> instance id -> name unique within that room
    layout: Layout  # footprints of the floor-standing objects
    type_mix: Mapping[str, float]  # high-level type -> relative share
    sight: SightMap | None = field(default=None, compare=False)  # walls that block the view (llm prompts)
    llm: Any = field(default=None, compare=False)  # instructions.llm.LLMInstructor in llm mode

    def object(self, instance_id: int) -> ObjectInfo:
        return next(o for o in self.objects if o.instance_id == instance_id)


def make_context(objects: Sequence[ObjectInfo], rooms: Sequence[RoomInfo], room_polygons: Mapping[str, np.ndarray],
                 footprints: Mapping[int, Sequence[np.ndarray]], *, fixtures: Sequence[ObjectInfo] = (),
                 doors: Collection[int] = (), type_mix: Mapping[str, float] | None = None,
                 sight: SightMap | None = None) -> SceneContext:
    """The context of a scene: names unique in the scene and within each room, relations from `footprints`.

    footprints: instance id -> exterior rings [K, 2] world metres, for the objects that may serve as
    landmarks (leave out what hangs above the agent); doors: instance ids of the objects that are doors,
    which get the rooms they join (`relations.rooms_joined`; without a footprint, their annotated room);
    type_mix: default all five types equally; sight: the walls that hide objects from a path (none:
    every object near a path counts as seen).
    """
    lay = layout(footprints)
    floors = {r.id: Polygon(room_polygons[r.id]) for r in rooms if r.id in room_polygons}

    def joined(o: ObjectInfo) -> tuple[str, ...]:
        return rooms_joined(lay.geoms[lay.index(o.instance_id)], floors) if o.instance_id in lay else \
            tuple(r for r in (o.room_id,) if r is not None)

    objects = [replace(o, joins=joined(o)) if o.instance_id in doors else o for o in objects]
    names = object_names(objects, rooms, lay)
    # a door is in the walls of every room it joins, and its name is the same seen from each
    local = {r.id: {**object_names([o for o in objects if o.room_id == r.id and o.joins is None], rooms, lay),
                    **{o.instance_id: names[o.instance_id] for o in objects
                       if r.id in (o.joins or ()) and o.instance_id in names}} for r in rooms}
    mix = {t: 1.0 for t in HIGH_LEVEL_TYPES} if type_mix is None else dict(type_mix)
    return SceneContext(tuple(objects), tuple(fixtures), tuple(rooms), dict(room_polygons),
                        names, room_names(rooms, objects), local, lay, mix, sight)


@dataclass(frozen=True)
class TrajectoryText:
    """What a generator may mention: the path's shape and the endpoints' unique names (never ids).

    The endpoint ids and rooms, and the scene, let high-level generators describe the goal other ways.
    """

    waypoints: np.ndarray  # [M, 4] float64 (x, y, z, yaw), metres and radians
    start_name: str  # e.g. "the dining table", "the kitchen"
    goal_name: str
    start_kind: Literal["object", "room"]
    goal_kind: Literal["object", "room"]
    start_id: int | None = None  # instance id of an object endpoint
    goal_id: int | None = None
    start_room: str | None = None  # room id the endpoint is in (its own id for a room)
    goal_room: str | None = None
    scene: SceneContext | None = None
    goal_radius: float = 1.0  # metres; Base_Action's literal execution must end this close to the last waypoint
    blocked: BlockedMap | None = None  # cells Base_Action's literal execution must not cross (None: not checked)
    high_level: tuple[str, str] | None = None  # (type, sentence) chosen with the scene's other trajectories


Generator = Callable[[TrajectoryText, np.random.Generator], list[Instruction]]
