"""Connected navigable regions and room reachability."""

from __future__ import annotations

import numpy as np

from sagebench.topdown.regions import label_regions, reachability


def _rooms(shape, **spans) -> dict[str, np.ndarray]:
    out = {}
    for name, (c0, c1) in spans.items():
        m = np.zeros(shape, bool)
        m[:, c0:c1] = True
        out[name] = m
    return out


def test_diagonal_steps_join_regions_and_numbering_is_row_major():
    nav = np.array([[1, 0, 0, 1], [0, 1, 0, 0], [0, 0, 0, 1]], bool)
    labels, count = label_regions(nav)
    assert count == 3
    assert labels.tolist() == [[1, 0, 0, 2], [0, 1, 0, 0], [0, 0, 0, 3]]


def test_rooms_sharing_a_region_reach_each_other():
    nav = np.zeros((5, 12), bool)
    nav[1:4, 0:5] = True  # rooms a and b, one region
    nav[1:4, 7:12] = True  # rooms c and d, another; columns 5 and 6 stay blocked
    masks = _rooms(nav.shape, a=(0, 3), b=(3, 5), c=(7, 9), d=(9, 12))
    reach = reachability(nav, masks)
    assert reach.region_cells == (15, 15)
    assert reach.room_regions == {"a": (1,), "b": (1,), "c": (2,), "d": (2,)}
    assert reach.reachable == {"a": ("b",), "b": ("a",), "c": ("d",), "d": ("c",)}
    assert not reach.all_rooms_connected()
    nav[2, 5:7] = True  # a corridor
    assert reachability(nav, masks).all_rooms_connected()


def test_a_room_without_navigable_floor_reaches_nothing():
    nav = np.ones((3, 6), bool)
    nav[:, 3:] = False
    reach = reachability(nav, _rooms(nav.shape, a=(0, 3), b=(3, 6)))
    assert reach.room_regions["b"] == () and reach.reachable == {"a": (), "b": ()}
    assert not reach.all_rooms_connected()
