"""Shortcutting: a kept segment never touches a blocked cell; waypoints carry world positions and headings."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from shapely.geometry import LineString, box

from profiles import examples

from sagebench.astar.grid_astar import astar
from sagebench.astar.shortcut import polyline_length, segment_clear, shortcut_indices, supercover, waypoints

RES = 0.05


def _touched_by_geometry(r0, c0, r1, c1):
    """Independent answer: cells whose closed unit square meets the segment between the two centres."""
    if (r0, c0) == (r1, c1):
        return {(r0, c0)}
    line = LineString([(c0 + 0.5, r0 + 0.5), (c1 + 0.5, r1 + 0.5)])
    return {(r, c) for r in range(min(r0, r1) - 1, max(r0, r1) + 2) for c in range(min(c0, c1) - 1, max(c0, c1) + 2)
            if box(c, r, c + 1, r + 1).intersects(line)}


@settings(max_examples=examples(400))
@given(st.integers(-6, 6), st.integers(-6, 6), st.integers(-6, 6), st.integers(-6, 6))
def test_supercover_is_every_cell_the_segment_touches(r0, c0, r1, c1):
    cells = supercover(r0, c0, r1, c1)
    assert {tuple(int(v) for v in c) for c in cells} == _touched_by_geometry(r0, c0, r1, c1)
    assert tuple(cells[0]) == (r0, c0) and tuple(cells[-1]) == (r1, c1)


def test_exact_corner_crossing_counts_both_side_cells():
    nav = np.ones((2, 2), dtype=np.uint8)
    nav[0, 1] = 0  # the diagonal (0,0)->(1,1) passes exactly through this cell's corner
    assert not segment_clear(nav, 0, 0, 1, 1)


@st.composite
def grids_with_paths(draw):
    h, w = draw(st.integers(2, 24)), draw(st.integers(2, 24))
    nav = (np.random.default_rng(draw(st.integers(0, 2**32 - 1))).random((h, w)) >= draw(
        st.sampled_from([0.1, 0.25, 0.4]))).astype(np.uint8)
    s = (draw(st.integers(0, h - 1)), draw(st.integers(0, w - 1)))
    g = (draw(st.integers(0, h - 1)), draw(st.integers(0, w - 1)))
    return nav, astar(nav, s, g, RES)


@settings(max_examples=examples(300))
@given(grids_with_paths())
def test_shortcut_segments_never_touch_blocked_cells(case):
    nav, path = case
    if path is None:
        return
    keep = shortcut_indices(nav, path.cells)
    assert keep[0] == 0 and keep[-1] == len(path.cells) - 1 and (np.diff(keep) > 0).all()
    pts = path.cells[keep]
    for a, b in zip(pts[:-1], pts[1:]):
        touched = _touched_by_geometry(int(a[0]), int(a[1]), int(b[0]), int(b[1]))
        assert all(nav[r, c] for r, c in touched)
    wps = waypoints(pts, RES, (0.0, 0.0), 0.0)
    assert polyline_length(wps) <= path.cost + 1e-9


def test_open_room_shortcuts_to_one_segment():
    nav = np.ones((40, 60), dtype=np.uint8)
    path = astar(nav, (3, 2), (30, 55), RES)
    keep = shortcut_indices(nav, path.cells)
    assert keep.tolist() == [0, len(path.cells) - 1]


def test_waypoints_are_cell_centres_with_next_segment_heading():
    cells = np.array([[0, 0], [0, 10], [10, 10]])
    wps = waypoints(cells, 0.1, (2.0, -1.0), 0.3)
    np.testing.assert_allclose(wps[:, :3], [[2.05, -0.95, 0.3], [3.05, -0.95, 0.3], [3.05, 0.05, 0.3]])
    np.testing.assert_allclose(wps[:, 3], [0.0, math.pi / 2, math.pi / 2])
    assert polyline_length(wps) == pytest.approx(2.0)


def test_a_passage_cell_stays_a_waypoint_at_its_anchor():
    """No shortcut crosses or starts at a passage cell (2): the path keeps it, joined by single steps, at its anchor."""
    nav = np.ones((3, 9), dtype=np.uint8)
    nav[0, :] = nav[2, :] = 0
    nav[1, 4] = 2
    cells = np.array([[1, c] for c in range(9)])
    keep = shortcut_indices(nav, cells)
    assert cells[keep].tolist() == [[1, 0], [1, 3], [1, 4], [1, 5], [1, 8]]
    wps = waypoints(cells[keep], 0.05, (0.0, 0.0), 0.0, {(1, 4): (0.231, 0.062)})
    assert wps[2, :2].tolist() == [0.231, 0.062] and np.allclose(wps[1, :2], [0.175, 0.075])
