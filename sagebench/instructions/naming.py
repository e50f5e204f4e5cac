"""Referring expressions that pick out exactly one object or room in a scene, with no internal ids.

An object is named by its category alone when that is unique in the scene; otherwise the first of
these that matches no other object of the category: colour, material, state, colour + material,
then the same with "in the <room>" added. A room is named by its type when that is unique, else by
its type plus an object category found in no other room of that type ("the bedroom with the desk").
Given footprints (a `relations.Layout`), an object no such rule singles out is named by a relation
to a landmark that has a plain name: "the chair next to the stove" when no other chair is next to
the stove, else "the nightstand closest to the wardrobe" when it is the closest chair by a clear
margin. Things no rule singles out get no name; the sampler leaves them out.

A door is named by the rooms it joins (`ObjectInfo.joins`), since it lies in the walls of both: "the
door between the study and the kitchen", "the outside door in the living room" (it joins one room, to
the outside or to unroomed space), "the outside door" (it joins none). When another door joins the same
rooms, an adjective that only this one of them has is added ("the open door between ..."); else the
door gets no name. Doors joining three or more rooms get none, and no door serves as a landmark.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from sagebench.instructions.relations import NEXT_TO_M, Layout, nearest, next_to

_ADJECTIVES: tuple[tuple[str, ...], ...] = (("colour",), ("material",), ("state",), ("colour", "material"))
LANDMARK_MAX_M = 3.0  # "closest to" only names landmarks this close to the object


@dataclass(frozen=True)
class ObjectInfo:
    instance_id: int
    category: str  # snake_case, e.g. "dining_table"
    room_id: str | None
    attributes: dict[str, str] = field(default_factory=dict)  # colour, material, state ...
    joins: tuple[str, ...] | None = None  # a door's rooms (relations.rooms_joined); None: not a door


def is_outside(door: ObjectInfo) -> bool:
    """A door joining fewer than two rooms leads outside (or to space no room covers)."""
    return door.joins is not None and len(door.joins) < 2


@dataclass(frozen=True)
class RoomInfo:
    id: str
    type: str  # snake_case, e.g. "living_room"


def words(snake: str) -> str:
    """"dining_table" -> "dining table"."""
    return snake.replace("_", " ").strip()


def object_names(objects: Sequence[ObjectInfo], rooms: Sequence[RoomInfo], lay: Layout | None = None) -> dict[int, str]:
    """instance_id -> unique noun phrase with article ("the grey armchair", "the plant in the study").

    With `lay` (footprints of at least `objects`), objects the plain rules miss get a relational name.
    """
    room_names_ = room_names(rooms, objects)
    by_category: dict[str, list[ObjectInfo]] = {}
    for obj in objects:
        by_category.setdefault(obj.category, []).append(obj)
    doors = [o for o in objects if o.joins is not None]
    out: dict[int, str] = {}
    for obj in objects:
        name = door_name(obj, doors, room_names_) if obj.joins is not None else \
            _object_name(obj, by_category[obj.category], room_names_)
        if name is not None:
            out[obj.instance_id] = name
    if lay is None:
        return out
    by_id = {o.instance_id: o for o in objects}
    landmarks = {i: n for i, n in out.items() if " in " not in n and by_id[i].joins is None}
    for obj in objects:
        if obj.instance_id not in out and obj.joins is None:
            name = relational_name(obj, by_category[obj.category], lay, landmarks, by_id)
            if name is not None:
                out[obj.instance_id] = name
    return out


def relational_name(obj: ObjectInfo, peers: Sequence[ObjectInfo], lay: Layout, landmarks: dict[int, str],
                    by_id: dict[int, ObjectInfo]) -> str | None:
    """"the <noun> next to <landmark>" or "the <noun> closest to <landmark>", unique among `peers`, else None.

    peers: the objects it must be told apart from (itself included); landmarks: instance id -> plain
    unique name; a landmark must be of another category and in the same room (not behind a wall).
    """
    if not all(p.instance_id in lay for p in peers) or obj.instance_id not in lay:
        return None  # a peer without a footprint cannot be told apart by position
    noun = words(obj.category)
    i = lay.index(obj.instance_id)
    peer_idx = [lay.index(p.instance_id) for p in peers]

    def usable(j: int) -> bool:
        lid = lay.ids[j]
        return lid in landmarks and by_id[lid].category != obj.category and by_id[lid].room_id == obj.room_id

    for j in next_to(lay, i):
        if usable(j) and sum(lay.gaps[p, j] <= NEXT_TO_M for p in peer_idx) == 1:
            return f"the {noun} next to {landmarks[lay.ids[j]]}"
    for j in np.argsort(lay.gaps[i], kind="stable"):
        if lay.gaps[i, j] > LANDMARK_MAX_M:
            break
        if usable(int(j)) and nearest(lay, peer_idx, int(j)) == i:
            return f"the {noun} closest to {landmarks[lay.ids[int(j)]]}"
    return None


def door_place(door: ObjectInfo, rooms: Mapping[str, str]) -> tuple[str, str] | None:
    """(noun, place) of a door from the rooms it joins: ("door", " between the study and the kitchen"),
    ("outside door", " in the kitchen"), ("outside door", ""); None when a room has no name or it joins more than two."""
    joins = door.joins or ()
    if len(joins) > 2 or not all(r in rooms for r in joins):
        return None
    noun = words(door.category)
    if len(joins) == 2:
        return noun, f" between {rooms[joins[0]]} and {rooms[joins[1]]}"
    return f"outside {noun}", "".join(f" in {rooms[r]}" for r in joins)


def door_peers(door: ObjectInfo, doors: Sequence[ObjectInfo]) -> list[ObjectInfo]:
    """The doors of its category that its place phrase fits too (those joining all its rooms; outside ones
    for an outside door): the ones a name must tell it apart from, itself included."""
    return [d for d in doors if d.category == door.category and set(door.joins or ()) <= set(d.joins or ())
            and (is_outside(d) or not is_outside(door))]


def door_name(door: ObjectInfo, doors: Sequence[ObjectInfo], rooms: Mapping[str, str]) -> str | None:
    """"the [adjectives] door between A and B" (module docstring), unique among `doors`, else None."""
    place = door_place(door, rooms)
    if place is None:
        return None
    noun, where = place
    peers = door_peers(door, doors)
    adjectives = "" if len(peers) == 1 else _telling_adjectives(door, peers)
    return None if adjectives is None else f"the {adjectives}{noun}{where}"


def _telling_adjectives(obj: ObjectInfo, pool: Sequence[ObjectInfo]) -> str | None:
    """"grey fabric ": the first attribute words (_ADJECTIVES) that only `obj` of `pool` has, else None."""
    for keys in _ADJECTIVES:
        if all(obj.attributes.get(k) for k in keys):
            wanted = tuple(obj.attributes[k] for k in keys)
            if sum(tuple(o.attributes.get(k) for k in keys) == wanted for o in pool) == 1:
                return "".join(f"{words(v)} " for v in wanted)
    return None


def _object_name(obj: ObjectInfo, same: list[ObjectInfo], rooms: dict[str, str]) -> str | None:
    noun = words(obj.category)
    if len(same) == 1:
        return f"the {noun}"
    place_options: list[str | None] = [None]
    if obj.room_id in rooms:
        place_options.append(obj.room_id)
    for place in place_options:
        pool = [o for o in same if place is None or o.room_id == place]
        suffix = "" if place is None else f" in {rooms[place]}"
        if place is not None and len(pool) == 1:
            return f"the {noun}{suffix}"
        adjectives = _telling_adjectives(obj, pool)
        if adjectives is not None:
            return f"the {adjectives}{noun}{suffix}"
    return None


def room_names(rooms: Sequence[RoomInfo], objects: Sequence[ObjectInfo]) -> dict[str, str]:
    """room id -> unique noun phrase with article ("the kitchen", "the bedroom with the desk")."""
    contents: dict[str, set[str]] = {r.id: set() for r in rooms}
    for obj in objects:
        if obj.room_id in contents:
            contents[obj.room_id].add(obj.category)
    out: dict[str, str] = {}
    for room in rooms:
        same = [r for r in rooms if r.type == room.type]
        if len(same) == 1:
            out[room.id] = f"the {words(room.type)}"
            continue
        others = set().union(*(contents[r.id] for r in same if r.id != room.id))
        only_here = sorted(contents[room.id] - others)
        if only_here:
            out[room.id] = f"the {words(room.type)} with the {words(only_here[0])}"
    return out
