"""Grid A*: optimal against the Dijkstra reference, never steps on or cuts past a blocked cell."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from profiles import examples

from sagebench.astar.dijkstra_reference import dijkstra_cost, path_cost
from sagebench.astar.grid_astar import Workspace, astar

RES = 0.05


@st.composite
def grid_and_endpoints(draw):
    h = draw(st.integers(1, 14))
    w = draw(st.integers(1, 14))
    density = draw(st.sampled_from([0.0, 0.15, 0.3, 0.45]))
    seed = draw(st.integers(0, 2**32 - 1))
    nav = (np.random.default_rng(seed).random((h, w)) >= density).astype(np.uint8)
    start = (draw(st.integers(0, h - 1)), draw(st.integers(0, w - 1)))
    goal = (draw(st.integers(0, h - 1)), draw(st.integers(0, w - 1)))
    return nav, start, goal


@st.composite
def rooms_and_endpoints(draw):
    """Open floors with rectangular obstacles: long straight and diagonal runs, where jump points matter."""
    h, w = draw(st.integers(8, 48)), draw(st.integers(8, 48))
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    nav = np.ones((h, w), dtype=np.uint8)
    for _ in range(draw(st.integers(0, 12))):
        r, c = rng.integers(0, h), rng.integers(0, w)
        nav[r:r + rng.integers(1, h // 2 + 1), c:c + rng.integers(1, w // 2 + 1)] = 0
    start = (draw(st.integers(0, h - 1)), draw(st.integers(0, w - 1)))
    goal = (draw(st.integers(0, h - 1)), draw(st.integers(0, w - 1)))
    return nav, start, goal


@settings(max_examples=examples(300))
@given(st.one_of(grid_and_endpoints(), rooms_and_endpoints()))
def test_cost_equals_dijkstra_and_no_path_exactly_when_dijkstra_has_none(case):
    nav, start, goal = case
    got = astar(nav, start, goal, RES)
    want = dijkstra_cost(nav, start, goal, RES)
    assert (got is None) == (want is None)
    if got is not None:
        assert got.cost == pytest.approx(want, rel=1e-12, abs=1e-12)


@settings(max_examples=examples(300))
@given(st.one_of(grid_and_endpoints(), rooms_and_endpoints()))
def test_path_is_legal_moves_on_navigable_cells(case):
    nav, start, goal = case
    got = astar(nav, start, goal, RES)
    if got is None:
        return
    cells = got.cells
    assert tuple(cells[0]) == start and tuple(cells[-1]) == goal
    assert nav[cells[:, 0], cells[:, 1]].all()
    steps = np.diff(cells.astype(int), axis=0)
    assert (np.abs(steps).max(axis=1, initial=1) == 1).all()
    for (r, c), (dr, dc) in zip(cells[:-1], steps):
        if dr and dc:  # a diagonal needs both orthogonal neighbours free
            assert nav[r + dr, c] and nav[r, c + dc]
    assert got.cost == pytest.approx(path_cost(cells, RES), rel=1e-12, abs=1e-12)


def test_open_floor_cost_is_octile_distance():
    nav = np.ones((300, 400), dtype=np.uint8)
    got = astar(nav, (0, 0), (299, 120), RES)
    assert got.cost == pytest.approx((120 * math.sqrt(2) + 179) * RES)


def test_no_corner_cutting_between_diagonal_blocks():
    nav = np.array([[1, 0], [0, 1]], dtype=np.uint8)
    assert astar(nav, (0, 0), (1, 1), RES) is None


def test_wall_with_door_goes_through_the_door():
    nav = np.ones((20, 20), dtype=np.uint8)
    nav[:, 10] = 0
    nav[17, 10] = 1
    got = astar(nav, (2, 2), (2, 17), RES)
    assert (17, 10) in {tuple(c) for c in got.cells}
    assert got.cost == pytest.approx(dijkstra_cost(nav, (2, 2), (2, 17), RES))


@pytest.mark.parametrize("start,goal", [((0, 0), (0, 3)), ((1, 1), (0, 0)), ((-1, 0), (0, 0)), ((0, 0), (5, 0))])
def test_blocked_or_outside_endpoints_are_no_path(start, goal):
    nav = np.ones((2, 4), dtype=np.uint8)
    nav[0, 3] = nav[1, 1] = 0
    assert astar(nav, start, goal, RES) is None


def test_workspace_reuse_gives_the_same_answers_as_fresh_searches():
    rng = np.random.default_rng(3)
    nav = (rng.random((60, 70)) > 0.3).astype(np.uint8)
    ws = Workspace(nav.shape)
    for _ in range(30):
        s = tuple(int(v) for v in rng.integers(0, 60, 2) % [60, 70])
        g = tuple(int(v) for v in rng.integers(0, 60, 2) % [60, 70])
        a, b = astar(nav, s, g, RES, ws), astar(nav, s, g, RES)
        assert (a is None) == (b is None)
        if a is not None:
            assert a.cost == b.cost and np.array_equal(a.cells, b.cells)
