"""Rasterisers agree with their plain references; grids follow the map convention."""

from __future__ import annotations

import numpy as np
import pytest
import shapely

from sagebench.topdown.occupancy import clip_to_band
from sagebench.topdown.raster import (
    Grid,
    polygon_mask,
    touched_cells,
    touched_cells_reference,
    triangle_centre_hits,
    triangle_centre_hits_reference,
)

GRID = Grid(origin=(-0.5, -0.25), resolution=0.1, shape=(17, 23))


def _random_tris(seed: int, n: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    centre = rng.uniform([-0.6, -0.4, 0.0], [2.0, 1.6, 1.0], size=(n, 1, 3))
    return centre + rng.normal(scale=[0.3, 0.3, 0.5], size=(n, 3, 3))


def _cells(rows, cols) -> set[tuple[int, int]]:
    return set(zip(rows.tolist(), cols.tolist()))


@pytest.mark.parametrize("seed", range(4))
def test_touched_cells_matches_shapely(seed):
    tris = _random_tris(seed, 40)
    tris[:10, :, 1] = tris[:10, :1, 1]  # vertical triangles: seen from above they are segments
    polys, _ = clip_to_band(tris, 0.3, 0.9)
    assert len(polys) > 10
    for poly in polys:
        assert _cells(*touched_cells(poly[None], GRID)) == _cells(*touched_cells_reference(poly[None], GRID))


@pytest.mark.parametrize("seed", range(3))
def test_triangle_centre_hits_matches_loop(seed):
    tris = _random_tris(seed, 30)
    fast = triangle_centre_hits(tris, GRID)
    slow = triangle_centre_hits_reference(tris, GRID)
    key = lambda h: sorted(zip(h[0].tolist(), h[1].tolist(), h[2].tolist(), np.round(h[3], 9).tolist()))  # noqa: E731
    assert len(fast[0]) > 50
    assert key(fast) == key(slow)


def test_centre_hits_give_the_height_of_a_tilted_plane():
    tris = np.array([[[0, 0, 0], [2, 0, 2], [0, 1.5, 0]], [[2, 0, 2], [2, 1.5, 2], [0, 1.5, 0]]], float)
    grid = Grid(origin=(0.0, 0.0), resolution=0.1, shape=(15, 20))  # exactly under the two triangles
    idx, rows, cols, z = triangle_centre_hits(tris, grid)
    xs, _ = grid.centres()
    np.testing.assert_allclose(z, xs[cols])  # z = x on this plane
    assert len(set(zip(rows.tolist(), cols.tolist()))) == 20 * 15  # every centre inside, shared edge included


def test_polygon_mask_counts_centres_or_touched_cells():
    square = shapely.box(0.02, 0.03, 0.52, 0.33)  # 0.5 x 0.3 m, off the grid lines
    assert polygon_mask(square, GRID).sum() == 5 * 3
    assert polygon_mask(square, GRID, touch=True).sum() == 6 * 4
    assert not polygon_mask(shapely.box(10, 10, 11, 11), GRID).any()


def test_grid_covering_snaps_origin_and_keeps_the_margin():
    g = Grid.covering(np.array([0.123, -1.01]), np.array([4.0, 2.0]), 0.05, margin=0.1)
    assert g.origin == (0.0, -1.15)
    xs, ys = g.centres()
    assert xs[0] - 0.025 <= 0.123 - 0.1 and xs[-1] + 0.025 >= 4.1 - 1e-9
    assert ys[0] - 0.025 <= -1.11 and ys[-1] + 0.025 >= 2.1 - 1e-9
