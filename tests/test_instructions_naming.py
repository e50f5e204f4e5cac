"""Referring expressions: each names exactly one thing, category first, then attribute or room; no ids."""

import numpy as np
from shapely.geometry import box

from sagebench.instructions.base import make_context
from sagebench.instructions.grounding import Grounder
from sagebench.instructions.naming import ObjectInfo, RoomInfo, object_names, room_names
from sagebench.instructions.relations import JOINS_M, rooms_joined

ROOMS = [RoomInfo("r1", "kitchen"), RoomInfo("r2", "living_room"), RoomInfo("r3", "bedroom"), RoomInfo("r4", "bedroom")]


def _obj(i, cat, room, **attrs):
    return ObjectInfo(i, cat, room, attrs)


def test_unique_category_is_named_by_category_alone():
    names = object_names([_obj(1, "dining_table", "r1", colour="white"), _obj(2, "sofa", "r2")], ROOMS)
    assert names == {1: "the dining table", 2: "the sofa"}


def test_two_chairs_of_different_colour_are_named_by_colour():
    names = object_names([_obj(1, "chair", "r1", colour="red"), _obj(2, "chair", "r1", colour="blue")], ROOMS)
    assert names == {1: "the red chair", 2: "the blue chair"}


def test_two_red_chairs_fall_back_to_material_then_room():
    objs = [_obj(1, "chair", "r1", colour="red", material="wood"), _obj(2, "chair", "r1", colour="red", material="metal"),
            _obj(3, "chair", "r2", colour="red", material="metal")]
    names = object_names(objs, ROOMS)
    assert names == {1: "the wood chair", 2: "the metal chair in the kitchen", 3: "the chair in the living room"}


def test_identical_objects_in_one_room_get_no_name():
    objs = [_obj(1, "nightstand", "r3", colour="white"), _obj(2, "nightstand", "r3", colour="white")]
    assert object_names(objs, ROOMS) == {}


def test_door_state_is_an_adjective():
    objs = [_obj(1, "door", "r1", state="open"), _obj(2, "door", "r1", state="closed")]
    assert object_names(objs, ROOMS) == {1: "the open door", 2: "the closed door"}


def test_rooms_of_a_repeated_type_are_told_apart_by_what_only_they_hold():
    objs = [_obj(1, "desk", "r3"), _obj(2, "bed", "r3"), _obj(3, "bed", "r4")]
    names = room_names(ROOMS, objs)
    assert names == {"r1": "the kitchen", "r2": "the living room", "r3": "the bedroom with the desk"}


def test_names_never_contain_ids():
    objs = [_obj(41, "chair", "r1", colour="red"), _obj(42, "chair", "r2", colour="red")]
    names = object_names(objs, ROOMS)
    assert names == {41: "the chair in the kitchen", 42: "the chair in the living room"}
    assert not any(ch.isdigit() for n in names.values() for ch in n)


# ---- doors are named by the rooms they join (relations.rooms_joined, computed once in make_context)

def _box(x0, y0, x1, y1):
    return np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]], dtype=np.float64)


# kitchen x 0..4, hallway x 4.1..8 (wall x 4..4.1), study y 4.1..8 above the kitchen (wall y 4..4.1)
_FLOORS = {"k": _box(0, 0, 4, 4), "h": _box(4.1, 0, 8, 4), "s": _box(0, 4.1, 4, 8)}
_ROOMS3 = [RoomInfo("k", "kitchen"), RoomInfo("h", "hallway"), RoomInfo("s", "study")]
_LEAVES = {1: _box(4.0, 1.0, 4.1, 2.0), 2: _box(1.0, 4.0, 2.0, 4.1), 3: _box(-0.1, 2.0, 0.0, 3.0),
           4: _box(4.0, 2.5, 4.1, 3.5)}  # 1: kitchen|hallway, 2: kitchen|study, 3: kitchen's west wall, 4: like 1


def _door_ctx(doors):
    """make_context on the three rooms; doors: instance id -> (annotated room, state)."""
    objs = [ObjectInfo(i, "door", room, {"state": state}) for i, (room, state) in doors.items()]
    return make_context(objs, _ROOMS3, _FLOORS, {i: [_LEAVES[i]] for i in doors}, doors=set(doors))


def test_a_door_is_named_by_the_two_rooms_or_the_one_room_it_joins():
    ctx = _door_ctx({1: ("k", "open"), 2: ("s", "open"), 3: ("k", "closed")})
    assert {o.instance_id: o.joins for o in ctx.objects} == {1: ("k", "h"), 2: ("k", "s"), 3: ("k",)}
    assert dict(ctx.names) == {1: "the door between the kitchen and the hallway",
                               2: "the door between the kitchen and the study", 3: "the outside door in the kitchen"}
    # a door is in the walls of both rooms, so each room's local names hold it
    assert set(ctx.local_names["k"]) == {1, 2, 3} and set(ctx.local_names["s"]) == {2}
    g = Grounder(ctx)
    for i, name in ctx.names.items():
        assert g.problems(f"Walk over to {name}.", goal_id=i) == [], name


def test_the_open_door_in_the_kitchen_is_ambiguous_when_two_open_doors_are_in_its_walls():
    # door 2 is annotated in the study, so the old rule named door 1 "the open door in the kitchen"
    ctx = _door_ctx({1: ("k", "open"), 2: ("s", "open"), 3: ("k", "closed")})
    assert "the open door in the kitchen" not in ctx.names.values()
    assert Grounder(ctx).problems("Walk over to the open door in the kitchen.", goal_id=1) == [
        "the open door in the kitchen could be any of 2 places; say which one is meant "
        "(the door between the kitchen and the hallway)"]


def test_two_doors_joining_the_same_rooms_are_told_apart_by_an_adjective_or_not_named():
    ctx = _door_ctx({1: ("k", "open"), 4: ("h", "closed"), 2: ("s", "open")})
    assert ctx.names[1] == "the open door between the kitchen and the hallway"
    assert ctx.names[4] == "the closed door between the kitchen and the hallway"
    g = Grounder(ctx)
    assert g.problems(f"Go to {ctx.names[4]}.", goal_id=4) == []
    assert "could be any of 2 places" in g.problems("Go to the door between the kitchen and the hallway.", goal_id=4)[0]
    twins = _door_ctx({1: ("k", "open"), 4: ("k", "open")})
    assert dict(twins.names) == {}  # no rule singles either out: neither becomes a goal


def test_a_door_joins_a_room_whose_floor_is_exactly_the_threshold_away():
    leaf = box(-1.0, 0.0, 0.0, 1.0)
    at = {"r": box(JOINS_M, 0.0, 2.0, 1.0)}  # the gap is JOINS_M to the last bit (0.3 - 0.0)
    beyond = {"r": box(float(np.nextafter(JOINS_M, 1.0)), 0.0, 2.0, 1.0)}
    assert rooms_joined(leaf, at) == ("r",)
    assert rooms_joined(leaf, beyond) == ()
