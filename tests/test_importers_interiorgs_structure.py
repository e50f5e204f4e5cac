"""The floor plan's geometry: walls with a door and a window cut, a leaf's state and swing from its box, room types."""

from __future__ import annotations

import math

import numpy as np
import pytest
import shapely
import trimesh

from sagebench.importers.boxes import OrientedBox
from sagebench.importers.interiorgs_files import Hole, WallSegment
from sagebench.importers.interiorgs_structure import (
    box_mesh, door_pose, openings_on, room_type, wall_pieces,
)
from sagebench.scene.loader import door_pose as posed
from sagebench.scene.model import Door

WALL = WallSegment(np.array([0.0, 0.0]), np.array([4.0, 0.0]), thickness=0.2, height=2.5)
DOOR = Hole(np.array([[1.0, 0.0, 0.0], [2.0, 0.0, 0.0], [2.0, 0.0, 2.1], [1.0, 0.0, 2.1]]), 0.2, "DOOR")
WINDOW = Hole(np.array([[2.5, 0.05, 0.9], [3.5, 0.05, 0.9], [3.5, 0.05, 2.0], [2.5, 0.05, 2.0]]), 0.2, "WINDOW")
ELSEWHERE = Hole(np.array([[1.0, 2.0, 0.0], [2.0, 2.0, 0.0], [2.0, 2.0, 2.1]]), 0.2, "DOOR")


def test_a_wall_keeps_what_no_opening_covers():
    openings = openings_on(WALL, (DOOR, ELSEWHERE, WINDOW), taken=set())
    assert [o.hole for o in openings] == [0, 2]  # the opening 2 m off the wall is not on it
    wall = trimesh.util.concatenate([box_mesh(b) for b in wall_pieces(WALL, openings)])
    elevation = shapely.box(-0.1, 0, 4.1, 2.5).difference(shapely.box(1, 0, 2, 2.1)).difference(shapely.box(2.5, 0.9, 3.5, 2.0))
    assert wall.volume == pytest.approx(elevation.area * 0.2)
    assert np.allclose(wall.bounds, [[-0.1, -0.1, 0.0], [4.1, 0.1, 2.5]])
    probe = np.array([[1.5, 0, 1.0], [3.0, 0, 1.5], [1.5, 0, 2.3], [3.0, 0, 0.5], [0.5, 0, 1.0]])
    inside = [any(b.contains(p[None])[0] for b in wall_pieces(WALL, openings)) for p in probe]
    assert inside == [False, False, True, True, True]  # doorway, window, lintel, sill, solid wall


def _leaf(hinge_x: float, turn_deg: float, side: int = 1) -> OrientedBox:
    """A 0.9 m leaf, 4 cm thick, hinged at (hinge_x, 0) in the door of WALL, turned by turn_deg (CCW) from
    pointing along +x (hinge at the opening's start) or -x (hinge at its end, side -1)."""
    a = math.radians(turn_deg) + (0.0 if side == 1 else math.pi)
    d = np.array([math.cos(a), math.sin(a)])
    centre = np.array([hinge_x, 0.0]) + d * 0.45
    return OrientedBox(np.array([*centre, 1.0]), np.array([[d[0], d[1], 0], [-d[1], d[0], 0], [0, 0, 1.0]]),
                       np.array([0.45, 0.02, 1.0]))


@pytest.mark.parametrize(("hinge_x", "side", "turn", "state", "swing"), [
    (1.0, 1, 90.0, "open", 1), (1.0, 1, -90.0, "open", -1), (2.0, -1, 45.0, "ajar", 1),
    (2.0, -1, -30.0, "ajar", -1), (1.0, 1, 0.0, "closed", 1), (1.0, 1, 4.0, "closed", 1),
])
def test_a_leaf_s_state_and_swing_come_from_its_box(hinge_x, side, turn, state, swing):
    (opening,) = openings_on(WALL, (DOOR,), taken=set())
    pose = door_pose(_leaf(hinge_x, turn, side), WALL, opening)
    assert (pose.state, pose.swing) == (state, swing)
    if state == "closed":  # a closed leaf does not show its hinge: either end of the opening will do
        assert pose.hinge in ((1.0, 0.0, 0.0), (2.0, 0.0, 0.0)) and pose.angle_deg == 0.0
    else:
        assert pose.hinge == pytest.approx((hinge_x, 0.0, 0.0))
        assert pose.angle_deg == pytest.approx(abs(turn))
        # the closed pose turned by sagebench's Door at that state lands where the leaf stands
        leaf = box_mesh(_leaf(hinge_x, turn, side))
        closed = leaf.copy().apply_transform(pose.closing())
        degrees = {"open_deg": pose.angle_deg} if state == "open" else {"ajar_deg": pose.angle_deg}
        door = Door(state=state, hinge=pose.hinge, swing=pose.swing, **degrees)
        assert np.allclose(closed.copy().apply_transform(posed(door)).vertices, leaf.vertices, atol=1e-9)
        assert np.allclose(closed.bounds[:, 1], [-0.02, 0.02], atol=1e-9)  # closed, it lies in the wall


@pytest.mark.parametrize(("given", "expected"), [
    ("Living and Dining Room", "living_room"), ("Master Bedroom", "bedroom"), ("Kitchen", "kitchen"),
    ("Secondary Bathroom", "bathroom"), ("Study", "study"), ("Wedding Banquet Hall", "wedding_banquet_hall"),
    ("", "room"), ("Balcony", "balcony"),
])
def test_room_types_in_sagebench_words(given, expected):
    assert room_type(given) == expected


def test_a_door_opening_takes_the_nearest_door_label_in_reach():
    """Two door labels within reach of one doorway (a leaf standing closed in it, and the open leaf of the next
    door along the corridor): the doorway's door is the leaf in it, and the other label stays a plain object,
    whatever order labels.json lists them in."""
    from types import SimpleNamespace

    from sagebench.importers.interiorgs import _match_doors, _Thing

    for order in ((0, 1), (1, 0)):
        leaves = {0: _leaf(1.0, 0.0), 1: _leaf(2.6, 90.0)}  # closed in the doorway; open, 1.3 m from its centre
        doors = [_Thing(0, "door", "object", label=k, box=leaves[k]) for k in order]
        wall = _Thing(0, "wall", "wall", segment=WALL, openings=openings_on(WALL, (DOOR,), taken=set()))
        _match_doors(doors, [wall], SimpleNamespace(holes=(DOOR,)), rooms=[])
        assert {d.label: (d.kind, d.door.state if d.door else None) for d in doors} == {
            0: ("door", "closed"), 1: ("object", None)}
