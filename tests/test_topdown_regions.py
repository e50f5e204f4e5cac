"""Connected navigable regions and room reachability."""

from __future__ import annotations

import numpy as np
import pytest

from sagebench.scene.model import Room
from sagebench.topdown.passages import PASSAGE
from sagebench.topdown.raster import Grid
from sagebench.topdown.regions import label_regions, reachability, room_reachability


def _rooms(shape, **spans) -> dict[str, np.ndarray]:
    out = {}
    for name, (c0, c1) in spans.items():
        m = np.zeros(shape, bool)
        m[:, c0:c1] = True
        out[name] = m
    return out


def test_cells_touching_only_diagonally_are_not_joined_and_numbering_is_row_major():
    # the planner never cuts a blocked corner, so it cannot step from (0, 0) to (1, 1) here
    nav = np.array([[1, 0, 0, 1], [0, 1, 0, 1], [0, 1, 1, 0]], bool)
    labels, count = label_regions(nav)
    assert count == 3
    assert labels.tolist() == [[1, 0, 0, 2], [0, 3, 0, 2], [0, 3, 3, 0]]


def test_rooms_sharing_a_region_reach_each_other():
    nav = np.zeros((5, 12), bool)
    nav[1:4, 0:5] = True  # rooms a and b, one region
    nav[1:4, 7:12] = True  # rooms c and d, another; columns 5 and 6 stay blocked
    masks = _rooms(nav.shape, a=(0, 3), b=(3, 5), c=(7, 9), d=(9, 12))
    reach = reachability(nav, masks)
    assert reach.region_cells == (15, 15) and reach.main_region == 1  # equal sizes: the lower id
    assert reach.room_regions == {"a": (1,), "b": (1,), "c": (2,), "d": (2,)}
    assert {r: reach.reachable_from(r) for r in masks} == {"a": ("b",), "b": ("a",), "c": ("d",), "d": ("c",)}
    assert [reach.room_reachable(r) for r in "abcd"] == [True, True, False, False]
    assert [reach.unreachable_cells(r) for r in "abcd"] == [0, 0, 6, 9]
    assert not reach.all_rooms_connected()
    nav[2, 5:7] = True  # a corridor
    assert reachability(nav, masks).all_rooms_connected()


def test_a_room_without_navigable_floor_reaches_nothing():
    nav = np.ones((3, 6), bool)
    nav[:, 3:] = False
    reach = reachability(nav, _rooms(nav.shape, a=(0, 3), b=(3, 6)))
    assert reach.room_regions["b"] == () and reach.reachable_from("a") == reach.reachable_from("b") == ()
    assert reach.room_reachable("a") and not reach.room_reachable("b") and reach.unreachable_cells("b") == 0
    assert not reach.all_rooms_connected()


def _split_room(in_main: int, outside: int) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """A main region of 40 cells (row 0) and room `r` on row 2: `in_main` cells joined to the main region by a
    column at col 0, `outside` more cells cut off beyond a blocked cell."""
    nav = np.zeros((3, 40), bool)
    nav[0] = True
    nav[1, 0] = True
    nav[2, :in_main] = True
    nav[2, in_main + 1:in_main + 1 + outside] = True
    room = np.zeros_like(nav)
    room[2] = True
    return nav, {"r": room}


@pytest.mark.parametrize("in_main, outside, reachable", [(5, 5, False), (6, 5, True), (1, 20, False), (20, 0, True)])
def test_a_room_is_reachable_only_when_more_than_half_its_floor_is_in_the_main_region(in_main, outside, reachable):
    reach = reachability(*_split_room(in_main, outside))
    assert reach.main_region == 1 and reach.room_main_cells["r"] == in_main and reach.room_cells["r"] == in_main + outside
    assert reach.room_reachable("r") is reachable  # exactly half (5 of 10) is not more than half
    assert reach.unreachable_cells("r") == outside
    assert reach.all_rooms_connected() is reachable


def test_room_reachability_of_two_rooms_a_wall_apart():
    """build-scene's regions step: each room's floor is the cells whose centre lies in its polygon; two rooms with
    a blocked column between are two regions, the bigger one main; one passage cell joins them."""
    grid = Grid(origin=(0.0, 0.0), resolution=1.0, shape=(3, 8))  # cell centres at x, y = 0.5, 1.5, ...
    rooms = [Room(id="a", type="office", polygon=[(0, 0), (3, 0), (3, 3), (0, 3)]),  # columns 0..2
             Room(id="b", type="hall", polygon=[(4, 0), (8, 0), (8, 3), (4, 3)])]  # columns 4..7
    nav = np.ones(grid.shape, np.uint8)
    nav[:, 3] = 0  # the wall
    reach = room_reachability(nav, rooms, grid)
    assert reach.region_cells == (9, 12) and reach.main_region == 2
    assert reach.room_regions == {"a": (1,), "b": (2,)} and reach.room_cells == {"a": 9, "b": 12}
    assert not reach.room_reachable("a") and reach.unreachable_cells("a") == 9 and reach.room_reachable("b")
    assert reach.reachable_from("a") == reach.reachable_from("b") == () and not reach.all_rooms_connected()
    nav[1, 3] = PASSAGE  # a passage cell counts as navigable
    joined = room_reachability(nav, rooms, grid)
    assert joined.region_cells == (22,) and joined.all_rooms_connected() and joined.reachable_from("a") == ("b",)
