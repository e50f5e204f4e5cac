"""Voxel colliders: the greedy box cover is exact, merging keeps coverage, boxes are trimmed to the mesh."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from sagebench.collider_export.quality import measure
from sagebench.collider_export.convex import hull_part
from sagebench.collider_export.quality import lattice_points, lattice_rows
from sagebench.collider_export.voxel import (_max_table, _rect_max, column_corners, greedy_boxes, greedy_boxes_reference,
                                            merge_boxes, run_ends, voxel_parts)
from tests.test_collider_pieces import inside_parts
from tests.test_collider_quality import BAND, L_SHAPE


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


@pytest.mark.parametrize("seed", range(5))
def test_compiled_greedy_boxes_equal_the_plain_ones(seed):
    solid = np.random.default_rng(seed).random((9, 7, 6)) < 0.7
    assert greedy_boxes(solid) == greedy_boxes_reference(solid)


def _same_hull(a: np.ndarray, b: np.ndarray) -> bool:
    pa, pb = hull_part(a), hull_part(b)
    return (np.array_equal(np.unique(pa.vertices.round(12), axis=0), np.unique(pb.vertices.round(12), axis=0)))


@pytest.mark.parametrize("seed", range(3))
def test_the_points_kept_for_each_owner_span_the_same_hull_as_all_of_them(seed):
    """run_ends and column_corners drop only points between kept ones: each owner's hull is unchanged."""
    rng = np.random.default_rng(seed)
    tri = rng.random((6, 3, 3))
    points, rows = lattice_rows(tri, 0.05)
    assert np.array_equal(points, lattice_points(tri, 0.05))
    owner = (points[:, 0] > 0.5).astype(np.int64) + 2 * (points[:, 2] > 0.4)
    keep = run_ends(rows, owner)
    assert keep.sum() < len(points) / 2
    cells = np.argwhere(rng.random((5, 4, 6)) < 0.6)
    cell_owner = (cells[:, 2] > 2).astype(np.int64)
    corners, corner_owner = column_corners(cells, cell_owner)
    every = (cells[:, None, :] + np.argwhere(np.ones((2, 2, 2), dtype=bool))[None]).reshape(-1, 3).astype(float)
    every_owner = np.repeat(cell_owner, 8)
    for k in np.unique(owner):
        assert _same_hull(points[keep & (owner == k)], points[owner == k])
    for k in (0, 1):
        assert _same_hull(corners[corner_owner == k], every[every_owner == k])


def test_merged_boxes_still_cover_the_solid_within_budget():
    solid = np.random.default_rng(1).random((8, 8, 4)) < 0.5
    merged = merge_boxes(greedy_boxes(solid), 5, np.ones(solid.shape[2]))
    assert len(merged) == 5
    assert np.all(_paint(merged, solid.shape)[solid] >= 1)


def test_merging_prefers_boxes_that_stay_on_the_band_footprint():
    # A and B touch diagonally, C lies 4 cells along from A; all in the band. By added volume A+B is the
    # cheapest merge (2 empty cells), but their box covers cell (0, 1), 3 cells off the footprint; A+C adds
    # 4 cells, all on it
    a, b, c = (0, 0, 0, 1, 1, 1), (1, 1, 0, 2, 2, 1), (5, 0, 0, 6, 1, 1)
    weights = np.ones(1)
    assert sorted(merge_boxes([a, b, c], 2, weights)) == [(0, 0, 0, 2, 2, 1), c]
    outside = np.zeros((6, 2))
    outside[0, 1] = 3.0
    assert sorted(merge_boxes([a, b, c], 2, weights, outside, tolerance=1.0)) == [(0, 0, 0, 6, 1, 1), b]
    # within the tolerance the overshoot is free and the volume decides again
    assert sorted(merge_boxes([a, b, c], 2, weights, outside, tolerance=3.0)) == [(0, 0, 0, 2, 2, 1), c]


@pytest.mark.parametrize("seed", range(5))
def test_rectangle_max_matches_a_plain_max(seed):
    rng = np.random.default_rng(seed)
    values = rng.random((13, 7))
    lo = np.stack([rng.integers(0, 13, 200), rng.integers(0, 7, 200)], axis=1)
    hi = lo + 1 + np.stack([rng.integers(0, 13, 200), rng.integers(0, 7, 200)], axis=1)
    hi = np.minimum(hi, [13, 7])
    plain = [values[x0:x1, y0:y1].max() for (x0, y0), (x1, y1) in zip(lo, hi)]
    assert np.array_equal(_rect_max(_max_table(values), lo, hi), plain)


def test_an_axis_aligned_l_comes_out_within_half_a_cell():
    parts = voxel_parts(L_SHAPE.vertices, L_SHAPE.faces, pitch=0.05, max_parts=8)
    q = measure(L_SHAPE.vertices, L_SHAPE.faces, parts, band=BAND)
    # each part is the hull of the L's points in its box: only a box across the notch's corner bridges it,
    # by less than half a cell (2.5 cm); the old box faces on the cell boundary reached exactly 2.5 cm past x = 1
    assert 0.0 < q.to_source_max_cm < 2.5
    # where the surface crosses from one box into the next the hulls leave a seam: at most a lattice spacing
    # (pitch / 2) wide, so no source point is farther than pitch / 4 from a part and the band loses one 1 cm cell
    assert q.band_over_cm <= 2.5 and q.band_under_cm <= 1.0 and 0.0 < q.from_source_max_cm < 1.25
    assert inside_parts(L_SHAPE.vertices, parts).all()


def test_an_open_mesh_is_covered_too():
    box = trimesh.creation.box((0.4, 0.3, 0.5)).apply_translation((0, 0, 0.25))
    open_box = trimesh.Trimesh(box.vertices, box.faces[2:], process=False)  # one side missing
    parts = voxel_parts(open_box.vertices, open_box.faces, pitch=0.02, max_parts=4)
    q = measure(open_box.vertices, open_box.faces, parts, band=BAND)
    assert q.band_over_cm <= 1.0 and q.band_under_cm <= 1.0
