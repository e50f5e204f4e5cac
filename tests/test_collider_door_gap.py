"""Door leaves clear the floor: collider parts cut DOOR_FLOOR_GAP_M above it, in the world frame."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from sagebench.collider_export.bodies import DOOR_FLOOR_GAP_M
from sagebench.collider_export.convex import hull_part
from sagebench.collider_export.door_gap import clear_floor


def test_a_leaf_down_to_the_floor_ends_the_gap_above_it_wherever_it_is_turned():
    leaf = hull_part(trimesh.creation.box((0.9, 0.04, 2.0)).apply_translation((0.45, 0, 1.0)).vertices)
    kick = hull_part(trimesh.creation.box((0.9, 0.05, 0.01)).apply_translation((0.45, 0, 0.005)).vertices)
    matrix = trimesh.transformations.rotation_matrix(0.7, [0, 0, 1])
    matrix[:3, 3] = (2.0, 1.0, 3.0)  # a floor at z = 3
    parts = clear_floor([leaf, kick], matrix, floor_z=3.0)
    assert len(parts) == 1  # the 1 cm kick plate lies wholly in the gap
    world = trimesh.transform_points(parts[0].vertices, matrix)
    assert world[:, 2].min() == pytest.approx(3.0 + DOOR_FLOOR_GAP_M)
    assert world[:, 2].max() == pytest.approx(5.0)
    # the rest of the leaf is untouched: the same footprint
    before = trimesh.transform_points(leaf.vertices, matrix)
    assert np.allclose(np.sort(world[:, :2], axis=0)[[0, -1]], np.sort(before[:, :2], axis=0)[[0, -1]])
    assert parts[0].volume == pytest.approx(0.9 * 0.04 * (2.0 - DOOR_FLOOR_GAP_M), rel=1e-9)


def test_parts_clear_of_the_floor_are_kept_as_they_are():
    top = hull_part(trimesh.creation.box((0.9, 0.04, 1.0)).apply_translation((0, 0, 1.5)).vertices)
    assert clear_floor([top], np.eye(4), floor_z=0.0)[0] is top
