"""Height-band clipping, band occupancy of real furniture meshes, and inflation by the agent radius."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

import shapely
import trimesh

from inline_scene import inline_scene
from profiles import examples

from sagebench.errors import ConfigError
from sagebench.scene import assets
from sagebench.topdown.footprints import mesh_parts
from sagebench.topdown.occupancy import band_occupancy, clip_to_band, inflate, inflate_reference, scene_occupancy
from sagebench.topdown.raster import Grid

GRID = Grid(origin=(-1.0, -1.0), resolution=0.05, shape=(40, 40))


def _area(poly: np.ndarray) -> float:
    x, y = poly[:, 0], poly[:, 1]
    return 0.5 * abs(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))


def test_clip_keeps_the_part_of_a_slope_inside_the_band():
    # a right triangle rising with x: z = x, legs 2 m along x and 1 m along y
    tri = np.array([[[0, 0, 0], [2, 0, 2], [0, 1, 0]]], float)
    polys, src = clip_to_band(tri, 0.5, 1.5)
    # the strip 0.5 <= x <= 1.5 of the triangle y <= 1 - x / 2
    assert src.tolist() == [0]
    assert _area(polys[0]) == pytest.approx(1.0 * (0.75 + 0.25) / 2)


def test_clip_drops_what_is_outside_and_keeps_a_wall_as_a_segment():
    flat_low = [[0, 0, 0.01], [1, 0, 0.01], [0, 1, 0.01]]
    wall = [[0, 0, 0], [1, 0, 0], [1, 0, 2.5]]
    polys, src = clip_to_band(np.array([flat_low, wall], float), 0.05, 1.2)
    assert src.tolist() == [1]
    assert _area(polys[0]) == pytest.approx(0.0) and np.ptp(polys[0][:, 0]) == pytest.approx(1 - 0.05 / 2.5)


def _occupancy(mesh, band_max=1.2):
    tris, part = mesh_parts(mesh)
    return band_occupancy(tris, part, GRID, 0.05, band_max)


def test_solid_body_blocks_inside_not_just_its_outline():
    # a built-in wardrobe, one closed box from the floor to 2 m: its bottom (0 m) is under the band and its top
    # above it, so only its sides cross the band; the inside must block too (only its span through the band says so)
    wardrobe = trimesh.creation.box(extents=(1.2, 0.6, 2.0))
    wardrobe.apply_translation((0.013, 0.012, 1.0))
    assert not clip_to_band(wardrobe.triangles[np.abs(wardrobe.face_normals[:, 2]) > 0.5], 0.05, 1.2)[1].size
    occ = _occupancy(wardrobe)
    r = np.nonzero(occ.any(axis=1))[0]
    c = np.nonzero(occ.any(axis=0))[0]
    assert occ[r[0] : r[-1] + 1, c[0] : c[-1] + 1].all()
    assert occ.sum() == pytest.approx((1.2 / 0.05 + 1) * (0.6 / 0.05 + 1), abs=30)


def test_l_sofa_blocks_an_l_and_a_lamp_above_the_band_nothing():
    sofa = assets.sofa_l(2.3, 1.6, 0.85, (0, 0, 200))
    sofa.apply_translation((0.011, 0.013, 0))
    occ = _occupancy(sofa)
    bbox_cells = (2.3 / 0.05) * (1.6 / 0.05)
    assert 0.5 * bbox_cells < occ.sum() < 0.9 * bbox_cells  # the corner in front of the long seat is free
    assert not _occupancy(assets.ceiling_lamp(0.5, 0.5, 0.8, (0, 0, 0))).any()
    assert not _occupancy(assets.rug(1.0, 1.0, 0.01, (0, 0, 0))).any()


def test_table_in_a_low_band_is_only_its_legs():
    table = assets.table(1.2, 0.8, 0.75, (0, 0, 0), leg=0.05)
    table.apply_translation((0.012, 0.011, 0))
    top = _occupancy(table)
    legs = _occupancy(table, band_max=0.5)
    assert legs.sum() == 4 * 4 and top.sum() == 25 * 17 and (legs <= top).all()


@settings(max_examples=examples(60))
@given(
    occ=arrays(np.uint8, st.tuples(st.integers(3, 14), st.integers(3, 14)), elements=st.sampled_from([0, 0, 0, 1])),
    radius=st.sampled_from([0.05, 0.1, 0.12, 0.2, 0.25]),
)
def test_inflation_is_exact(occ, radius):
    nav = inflate(occ, radius, 0.05)
    np.testing.assert_array_equal(nav, inflate_reference(occ, radius, 0.05))
    # no navigable centre lies within the radius of any point of a blocked cell (its nearest corner or edge)
    blocked = np.argwhere(occ != 0)
    for r, c in np.argwhere(nav):
        if len(blocked):
            gap = np.hypot(np.maximum(np.abs(blocked[:, 0] - r) - 0.5, 0), np.maximum(np.abs(blocked[:, 1] - c) - 0.5, 0))
            assert gap.min() * 0.05 >= radius - 1e-9


# ---------------------------------------------------------------- the step: a scene's objects on the map's grid


def test_scene_occupancy_of_one_box_in_the_band():
    """build-scene's occupancy step: a 0.2 m box blocks its 5 x 5 cells and the cells off the floor plan block;
    a floor slab and a ceiling reaching into the band, and a lamp above it, block nothing; inflation follows."""
    things = [("floor", "floor", trimesh.creation.box(bounds=[(-0.8, -0.8, -0.05), (0.8, 0.8, 0.1)])),
              ("ceiling", "ceiling", trimesh.creation.box(bounds=[(-0.8, -0.8, 1.0), (0.8, 0.8, 1.1)])),
              ("cabinet", "object", trimesh.creation.box(bounds=[(0.012, 0.011, 0.0), (0.212, 0.211, 0.5)])),
              ("lamp", "object", trimesh.creation.box(bounds=[(-0.5, -0.5, 1.8), (-0.3, -0.3, 2.0)]))]
    objects = inline_scene(things).spec.objects
    parts = {o.instance_id: mesh_parts(mesh) for o, (_, _, mesh) in zip(objects, things)}
    occ = scene_occupancy(objects, parts, shapely.box(-0.8, -0.8, 0.8, 0.8), GRID, (0.05, 1.2), 0.2)
    expected = np.ones(GRID.shape, bool)
    expected[4:36, 4:36] = False  # the cells whose centre lies on the plan
    expected[20:25, 20:25] = True  # the cabinet: x, y 0.012 .. 0.212 m
    np.testing.assert_array_equal(occ.occupied, expected)
    np.testing.assert_array_equal(occ.navigable, inflate(expected, 0.2, 0.05))
    assert occ.blocking == {3}
    assert len(occ.band_polys) == 10  # the cabinet's sides and top; its bottom lies under the band
    lo, hi = occ.band_polys.min(axis=(0, 1)), occ.band_polys.max(axis=(0, 1))  # world m, as the cabinet stands
    assert np.allclose(lo, (0.012, 0.011)) and np.allclose(hi, (0.212, 0.211))
    with pytest.raises(ConfigError) as err:
        scene_occupancy(objects, parts, shapely.box(-0.8, -0.8, 0.8, 0.8), GRID, (0.05, 1.2), 0.9)
    assert str(err.value) == ("agent.radius: an agent of radius 0.9 m fits nowhere on the floor: no navigable cell "
                              "(a smaller agent radius, or a scene with free floor)")
