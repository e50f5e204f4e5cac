"""Voxel colliders: the greedy box cover is exact, merging keeps coverage, boxes are trimmed to the mesh."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from sagebench.collider_export.quality import measure
from sagebench.collider_export.voxel import greedy_boxes, merge_boxes, voxel_parts
from tests.test_collider_pieces import inside_parts
from tests.test_collider_quality import L_SHAPE


def _paint(boxes, shape) -> np.ndarray:
    count = np.zeros(shape, dtype=int)
    for i0, j0, k0, i1, j1, k1 in boxes:
        count[i0:i1, j0:j1, k0:k1] += 1
    return count


@pytest.mark.parametrize("seed", range(5))
def test_greedy_boxes_cover_every_solid_cell_once(seed):
    solid = np.random.default_rng(seed).random((7, 6, 5)) < 0.6
    count = _paint(greedy_boxes(solid), solid.shape)
    assert np.array_equal(count, solid.astype(int))


def test_merged_boxes_still_cover_the_solid_within_budget():
    solid = np.random.default_rng(1).random((8, 8, 4)) < 0.5
    merged = merge_boxes(greedy_boxes(solid), 5, np.ones(solid.shape[2]))
    assert len(merged) == 5
    assert np.all(_paint(merged, solid.shape)[solid] >= 1)


def test_an_axis_aligned_l_comes_out_within_half_a_cell():
    parts = voxel_parts(L_SHAPE.vertices, L_SHAPE.faces, pitch=0.05, max_parts=8)
    q = measure(L_SHAPE.vertices, L_SHAPE.faces, parts)
    # a box face with empty space beyond it is pulled onto the L; one beside the notch's corner, half empty
    # beyond, stays on the cell boundary half a cell (2.5 cm) past x = 1
    assert q.to_source_max_cm == pytest.approx(2.5, abs=1e-6)
    assert q.band_over_cm <= 2.5 and q.band_under_cm == 0.0 and q.from_source_max_cm < 1e-6
    assert inside_parts(L_SHAPE.vertices, parts).all()


def test_an_open_mesh_is_covered_too():
    box = trimesh.creation.box((0.4, 0.3, 0.5)).apply_translation((0, 0, 0.25))
    open_box = trimesh.Trimesh(box.vertices, box.faces[2:], process=False)  # one side missing
    parts = voxel_parts(open_box.vertices, open_box.faces, pitch=0.02, max_parts=4)
    q = measure(open_box.vertices, open_box.faces, parts)
    assert q.band_over_cm <= 1.0 and q.band_under_cm <= 1.0
