"""Referring expressions: each names exactly one thing, category first, then attribute or room; no ids."""

from sagebench.instructions.naming import ObjectInfo, RoomInfo, object_names, room_names

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
