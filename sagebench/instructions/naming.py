"""Referring expressions that pick out exactly one object or room in a scene, with no internal ids.

An object is named by its category alone when that is unique in the scene; otherwise the first of
these that matches no other object of the category: colour, material, state, colour + material,
then the same with "in the <room>" added. A room is named by its type when that is unique, else by
its type plus an object category found in no other room of that type ("the bedroom with the desk").
Given footprints (a `relations.Layout`), an object no such rule singles out is named by a relation
to a landmark that has a plain name: "the chair next to the stove" when no other chair is next to
the stove, else "the nightstand closest to the wardrobe" when it is the closest chair by a clear
margin. Things no rule singles out get no name; the sampler leaves them out.
"""

from __future__ import annotations

from collections.abc import Sequence
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
    out: dict[int, str] = {}
    for obj in objects:
        name = _object_name(obj, by_category[obj.category], room_names_)
        if name is not None:
            out[obj.instance_id] = name
    if lay is None:
        return out
    landmarks = {i: n for i, n in out.items() if " in " not in n}
    by_id = {o.instance_id: o for o in objects}
    for obj in objects:
        if obj.instance_id not in out:
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
        for keys in _ADJECTIVES:
            if not all(obj.attributes.get(k) for k in keys):
                continue
            wanted = tuple(obj.attributes[k] for k in keys)
            if sum(tuple(o.attributes.get(k) for k in keys) == wanted for o in pool) == 1:
                return f"the {' '.join(words(v) for v in wanted)} {noun}{suffix}"
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
