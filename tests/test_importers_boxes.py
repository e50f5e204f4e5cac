"""Oriented boxes from 8 corners in any order, and the tightest box per point against a plain reference."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from sagebench.importers.boxes import BoxError, OrientedBox, box_from_corners, box_owner, box_owner_reference


def _box(centre, yaw: float, half) -> OrientedBox:
    c, s = math.cos(yaw), math.sin(yaw)
    return OrientedBox(np.asarray(centre, float), np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]]),
                       np.asarray(half, float))


@given(st.floats(-math.pi, math.pi), st.lists(st.floats(0.01, 3.0), min_size=3, max_size=3),
       st.permutations(range(8)))
def test_any_corner_order_gives_back_the_box(yaw, half, order):
    box = _box((1.0, -2.0, 0.5), yaw, half)
    got = box_from_corners(box.corners()[list(order)])
    assert got.volume == pytest.approx(box.volume, rel=1e-9)
    assert np.allclose(got.centre, box.centre)
    assert got.axes[2] == pytest.approx([0, 0, 1])  # the vertical axis comes last, pointing up
    assert np.linalg.det(got.axes) == pytest.approx(1.0)
    # the same points are inside either way
    probe = np.random.default_rng(0).uniform(-3, 3, (200, 3)) + box.centre
    assert np.array_equal(got.contains(probe), box.contains(probe))


def test_corners_come_bottom_face_first_counter_clockwise():
    c = _box((0, 0, 1), 0.3, (2, 1, 1)).corners()
    assert (c[:4, 2] == 0).all() and (c[4:, 2] == 2).all()
    ring = c[:4, :2]
    area2 = sum(ring[i, 0] * ring[(i + 1) % 4, 1] - ring[(i + 1) % 4, 0] * ring[i, 1] for i in range(4))
    assert area2 == pytest.approx(2 * 4 * 2)  # positive: counter-clockwise; the footprint is 4 x 2 m


@pytest.mark.parametrize(("corners", "message"), [
    (np.zeros((8, 3)), "zero volume"),
    (np.array([[x, y, 0.0] for x in (0, 1) for y in (0, 1)] * 2), "zero volume"),  # flat: corners repeated
    (np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)]) + np.eye(8, 3) * 0.4,
     "not those of a box"),
])
def test_what_is_no_box_is_refused(corners, message):
    with pytest.raises(BoxError, match=message):
        box_from_corners(corners)


@given(st.integers(0, 2**32 - 1))
def test_tightest_box_matches_the_plain_reference(seed):
    rng = np.random.default_rng(seed)
    boxes = [_box(rng.uniform(-2, 2, 3), rng.uniform(-math.pi, math.pi), rng.uniform(0.1, 1.5, 3)) for _ in range(6)]
    boxes.append(boxes[0])  # an equal box: the later one wins in both
    points = rng.uniform(-3, 3, (300, 3))
    assert np.array_equal(box_owner(points, boxes, 0.05), box_owner_reference(points, boxes, 0.05))


def test_nested_boxes_give_the_inner_one():
    outer, inner = _box((0, 0, 0), 0.0, (1, 1, 1)), _box((0.5, 0, 0), 0.7, (0.2, 0.2, 0.2))
    owner = box_owner(np.array([[0.5, 0, 0], [-0.5, 0, 0], [3, 0, 0]]), [outer, inner])
    assert owner.tolist() == [1, 0, -1]
