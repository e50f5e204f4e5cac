"""Spatial relations from footprints: next to, nearest by a margin, between, left/right as seen from a point, rooms and objects along a path."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from shapely.geometry import Polygon

from profiles import examples

from sagebench.instructions.relations import (between, layout, nearest, next_to, objects_passed, rooms_along,
                                              side_as_seen)


def _box(x0, y0, x1, y1):
    return [np.array([(x0, y0), (x1, y0), (x1, y1), (x0, y1)], dtype=np.float64)]


# a table at the origin, a chair touching its east side, a second chair 2 m east, a lamp 5 m north
FOOT = {1: _box(0, 0, 1, 1), 2: _box(1.2, 0.2, 1.6, 0.6), 3: _box(3.0, 0.2, 3.4, 0.6), 4: _box(0, 5, 0.4, 5.4)}


def test_gaps_are_footprint_distances_and_next_to_uses_them():
    lay = layout(FOOT)
    assert lay.gaps[lay.index(1), lay.index(2)] == pytest.approx(0.2)
    assert lay.gaps[lay.index(2), lay.index(3)] == pytest.approx(1.4)
    assert lay.gaps[lay.index(1), lay.index(4)] == pytest.approx(4.0)
    assert np.isinf(np.diag(lay.gaps)).all()
    assert [lay.ids[j] for j in next_to(lay, lay.index(1))] == [2]
    assert lay.centroids[lay.index(1)].tolist() == pytest.approx([0.5, 0.5])


@settings(max_examples=examples(30))
@given(st.lists(st.tuples(st.floats(-5, 5), st.floats(-5, 5), st.floats(0.1, 2), st.floats(0.1, 2)), min_size=2,
                max_size=6))
def test_gap_matrix_matches_pairwise_shapely_distances(boxes):
    foot = {i + 1: _box(x, y, x + w, y + h) for i, (x, y, w, h) in enumerate(boxes)}
    lay = layout(foot)
    for a in foot:
        for b in foot:
            if a != b:
                ref = Polygon(foot[a][0]).distance(Polygon(foot[b][0]))
                assert lay.gaps[lay.index(a), lay.index(b)] == pytest.approx(ref, abs=1e-9)


def test_nearest_needs_a_clear_margin():
    lay = layout(FOOT)
    chairs = [lay.index(2), lay.index(3)]
    assert lay.ids[nearest(lay, chairs, lay.index(1))] == 2  # 0.2 m vs 2.0 m from the table
    close = layout({1: _box(0, 0, 1, 1), 2: _box(1.2, 0, 1.4, 0.2), 3: _box(-0.5, 0, -0.3, 0.2)})
    assert nearest(close, [close.index(2), close.index(3)], close.index(1)) is None  # 0.2 m vs 0.3 m


def test_between_needs_the_object_inside_the_segment_and_close_to_both():
    lay = layout({1: _box(0, 0, 1, 1), 2: _box(2, 0, 3, 1), 3: _box(1.3, 0.3, 1.7, 0.7), 4: _box(4, 0, 4.5, 1)})
    i = {k: lay.index(k) for k in (1, 2, 3, 4)}
    assert between(lay, i[3], i[1], i[2])
    assert not between(lay, i[4], i[1], i[2])  # beyond b
    assert not between(lay, i[1], i[3], i[2])  # a lies outside the segment 3-2
    far = layout({1: _box(0, 0, 1, 1), 2: _box(2, 0, 3, 1), 3: _box(1.3, 2.5, 1.7, 2.9)})
    assert not between(far, far.index(3), far.index(1), far.index(2))  # off to the side


def test_side_as_seen_from_a_viewer_facing_the_landmark():
    viewer, landmark = np.array([0.0, 0.0]), np.array([4.0, 0.0])
    assert side_as_seen(viewer, landmark, np.array([4.0, 1.0])) == "left"
    assert side_as_seen(viewer, landmark, np.array([4.0, -1.0])) == "right"
    assert side_as_seen(viewer, landmark, np.array([6.0, 0.1])) is None  # straight behind it
    # facing the other way the same two points swap sides
    assert side_as_seen(np.array([8.0, 0.0]), landmark, np.array([4.0, 1.0])) == "right"


def test_rooms_and_objects_along_a_path_in_walking_order():
    rooms = {"a": np.array([(0, 0), (4, 0), (4, 4), (0, 4)], float), "b": np.array([(4, 0), (8, 0), (8, 4), (4, 4)], float)}
    path = np.array([(1.0, 2.0), (7.0, 2.0), (1.0, 2.5)])
    assert rooms_along(path, rooms) == ["a", "b", "a"]
    lay = layout({1: _box(6, 2.8, 6.5, 3.2), 2: _box(2, 1.0, 2.5, 1.5), 3: _box(2, -3, 2.5, -2.5)})
    assert [lay.ids[j] for j in objects_passed(lay, path[:2])] == [2, 1]


def test_a_footprint_ring_that_crosses_itself_is_still_laid_out():
    """Real artist meshes give such rings (GEOS refused to union them: 'side location conflict')."""
    bowtie = np.array([(0.0, 0.0), (1.0, 1.0), (1.0, 0.0), (0.0, 1.0)])
    lay = layout({1: [bowtie, np.array([(0.2, 0.0), (0.8, 0.0), (0.5, 0.4)])], 2: [np.array([(3.0, 0), (4, 0), (4, 1)])]})
    assert lay.gaps[0, 1] == pytest.approx(2.0)
