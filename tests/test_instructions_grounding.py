"""Grounding check: mentions must exist in the scene, attributes must fit, ids/coordinates/numbers are rejected."""

import numpy as np
import pytest

from sagebench.instructions.base import make_context
from sagebench.instructions.grounding import Grounder
from sagebench.instructions.naming import ObjectInfo, RoomInfo


@pytest.fixture(scope="module")
def grounder():
    objects = [ObjectInfo(1, "dining_table", "k", {"colour": "white", "material": "wood"}),
               ObjectInfo(2, "chair", "k", {"colour": "red"}), ObjectInfo(3, "chair", "k", {"colour": "blue"}),
               ObjectInfo(4, "floor_lamp", "l", {"colour": "black"}), ObjectInfo(5, "sofa", "l", {"colour": "grey"}),
               ObjectInfo(6, "door", "l", {"state": "ajar"})]
    rooms = [RoomInfo("k", "kitchen"), RoomInfo("l", "living_room")]
    polys = {"k": np.array([(0, 0), (4, 0), (4, 4), (0, 4)], float), "l": np.array([(4, 0), (8, 0), (8, 4), (4, 4)], float)}
    ctx = make_context(objects, rooms, polys, {}, fixtures=[ObjectInfo(9, "window", "l", {"material": "glass"})])
    return Grounder(ctx)


@pytest.mark.parametrize("text", [
    "Go to the white wooden dining table in the kitchen.",
    "Walk past the couch and stop at the black lamp.",  # synonym; a generic head noun ("lamp")
    "Find the red chair near the table, then wait.",
    "Bring a cup of tea to the grey sofa in the lounge.",  # carried items are not scene objects
    "Stand by the window in the living room.",  # fixtures count
    "Go through the ajar door into the kitchen.",
    "Walk between the chairs and stop at the sofa.",  # plural
])
def test_grounded_texts_pass(grounder, text):
    assert grounder.problems(text) == []


@pytest.mark.parametrize("text,problem", [
    ("Go to the piano in the living room.", "there is no piano in this scene"),
    ("Walk into the garage and stop there.", "there is no garage in this scene"),
    ("Find the green chair in the kitchen.", "there is no green chair in this scene"),
    ("Go to the wooden sofa by the window.", "there is no wood sofa in this scene"),
    ("Go to room_2 and find the sofa.", "it contains an internal id or name"),
    ("Walk to object 41 in the kitchen.", "it contains an internal id or name"),
    ("Go to the sofa at #5 please.", "it contains an internal id or name"),
    ("Walk to the dining_table now.", "it contains an internal id or name"),
    ("Go to the sofa at 3.5, 2.0 now.", "it contains coordinates"),
    ("Walk to the sofa, about 3 steps away.", "it contains a number"),
    ("Sofa.", "it is 1 words long, not 4-30"),
])
def test_ungrounded_texts_are_rejected_with_the_reason(grounder, text, problem):
    assert problem in grounder.problems(text)


def test_the_goal_must_be_mentioned(grounder):
    assert grounder.problems("Go to the grey sofa now.", goal_category="sofa") == []
    assert grounder.problems("Go to the grey sofa now.", goal_category="dining_table") == [
        "it does not mention the goal, dining table"]
    assert grounder.problems("Go to the table in the kitchen.", goal_category="dining_table") == []
    assert grounder.problems("Head into the kitchen and stop.", goal_room_type="kitchen") == []
    assert grounder.problems("Go to the room with the sofa.", goal_room_type="living_room") == []
    assert grounder.problems("Go to the sofa and stop.", goal_room_type="kitchen") == [
        "it does not mention the goal, kitchen"]


def test_mentions_prefer_the_longest_phrase_and_read_adjectives(grounder):
    ms = grounder.mentions("Put the red chairs by the white wooden dining table in the Living Room")
    assert [(m.kind, m.phrase, m.adjectives) for m in ms] == [
        ("object", "chair", ("red",)), ("object", "dining table", ("white", "wood")), ("room", "living room", ())]
