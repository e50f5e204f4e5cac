"""Transforms and door poses have the meaning the input format documents."""

import math

import numpy as np
import pytest
from pydantic import ValidationError

from sagebench.scene.loader import door_pose, yaw_quaternion
from sagebench.scene.model import Door, Transform


def test_trs_scales_then_rotates_then_translates():
    t = Transform(translation=(1, 2, 3), rotation_wxyz=yaw_quaternion(math.pi / 2), scale=(2, 1, 1))
    p = t.as_matrix() @ np.array([1.0, 0, 0, 1])
    np.testing.assert_allclose(p[:3], [1, 4, 3], atol=1e-12)  # (2,0,0) turned to (0,2,0), then moved


def test_matrix_form_is_used_verbatim():
    m = ((1, 0, 0, 5), (0, 1, 0, 0), (0, 0, 1, 0), (0, 0, 0, 1))
    np.testing.assert_array_equal(Transform(matrix=m).as_matrix()[:3, 3], [5, 0, 0])


def test_matrix_and_trs_together_is_an_error():
    with pytest.raises(ValidationError, match="give either matrix or translation"):
        Transform(translation=(1, 0, 0), matrix=((1, 0, 0, 0), (0, 1, 0, 0), (0, 0, 1, 0), (0, 0, 0, 1)))


def test_rotation_is_normalised():
    t = Transform(rotation_wxyz=(2, 0, 0, 0))
    assert t.rotation_wxyz == (1, 0, 0, 0)


@pytest.mark.parametrize(("state", "swing", "deg"), [("closed", 1, 0), ("open", 1, 90), ("ajar", -1, -45)])
def test_door_leaf_turns_about_its_hinge(state, swing, deg):
    door = Door(state=state, hinge=(1.0, 0.0, 0.0), swing=swing)
    far_end = door_pose(door) @ np.array([2.0, 0, 0, 1])  # 1 m from the hinge along +X when closed
    a = math.radians(deg)
    np.testing.assert_allclose(far_end[:3], [1 + math.cos(a), math.sin(a), 0], atol=1e-12)
