"""Footprints from surface samples: known areas, per-part hulls, determinism."""

from __future__ import annotations

import numpy as np
import pytest
import shapely
import trimesh

from inline_scene import inline_scene
from meshes import prism, wall_with_openings

from sagebench.scene import assets
from sagebench.settings.build_scene import BuildSceneConfig
from sagebench.topdown.footprints import (band_section, footprint, footprint_reference, mesh_parts, object_footprints,
                                          sample_surface)

DENSITY = BuildSceneConfig().sample_density


def _fp(mesh: trimesh.Trimesh, seed: int = 0):
    tris, part = mesh_parts(mesh)
    return footprint(tris, part, DENSITY, np.random.default_rng(seed), min_width=0.05)


@pytest.mark.parametrize("extents", [(1.0, 0.6, 0.5), (0.4, 0.4, 0.9), (2.0, 0.9, 0.75)])
def test_box_footprint_area_within_one_percent(extents):
    box = trimesh.creation.box(extents=extents)
    box.apply_transform(trimesh.transformations.rotation_matrix(0.3, [0, 0, 1]))
    assert _fp(box).area == pytest.approx(extents[0] * extents[1], rel=0.01)


def test_l_sofa_is_an_l_not_its_bounding_rectangle():
    sofa = assets.sofa_l(2.3, 1.6, 0.85, (0, 0, 200))
    fp = _fp(sofa)
    exact = footprint_reference(*mesh_parts(sofa))
    assert fp.area == pytest.approx(exact.area, rel=0.01)
    assert fp.symmetric_difference(exact).area < 0.01 * exact.area
    assert fp.area < 0.8 * shapely.box(*fp.bounds).area


def test_table_footprint_is_its_top_and_legs_are_parts():
    table = assets.table(1.2, 0.8, 0.75, (0, 0, 0))
    tris, part = mesh_parts(table)
    assert len(np.unique(part)) == 5
    assert _fp(table).area == pytest.approx(1.2 * 0.8, rel=0.01)


def test_parts_join_split_vertices_and_separate_pieces():
    box = trimesh.creation.box(extents=(1, 1, 1))
    unmerged = trimesh.Trimesh(box.vertices[box.faces].reshape(-1, 3), np.arange(36).reshape(12, 3), process=False)
    assert len(np.unique(mesh_parts(unmerged)[1])) == 1
    two = trimesh.util.concatenate([box, box.copy().apply_translation((3, 0, 0))])
    tris, part = mesh_parts(two)
    assert len(np.unique(part)) == 2
    fp = _fp(two)
    assert fp.geom_type == "MultiPolygon" and fp.area == pytest.approx(2.0, rel=0.01)


def test_a_vertical_panel_still_has_a_footprint():
    panel = trimesh.Trimesh([[0, 0, 0], [1, 0, 0], [1, 0, 1], [0, 0, 1]], [[0, 1, 2], [0, 2, 3]], process=False)
    assert _fp(panel).area == pytest.approx(1.0 * 0.05, rel=0.05)


def test_samples_are_uniform_by_area_and_seeded():
    big = trimesh.creation.box(extents=(1, 1, 0.001))  # top and bottom carry almost all the area
    tris, _ = mesh_parts(big)
    pts = sample_surface(tris, 20000, np.random.default_rng(1))
    assert np.abs(pts[:, 2]).max() <= 0.0005 + 1e-12
    assert abs((pts[:, 0] < 0).mean() - 0.5) < 0.02
    again = sample_surface(tris, 20000, np.random.default_rng(1))
    np.testing.assert_array_equal(pts, again)
    assert _fp(assets.plant(0.5, 0.5, 1.1, (0, 0, 0)), seed=3).equals_exact(
        _fp(assets.plant(0.5, 0.5, 1.1, (0, 0, 0)), seed=3), 0.0)


def test_a_vertical_panel_along_y_keeps_its_area_and_length():
    """Its samples all share one x: the chord must still run along y (keyed on x alone it shrank to a 5 cm square)."""
    panel = trimesh.Trimesh([[0, 0, 0], [0, 1, 0], [0, 1, 1], [0, 0, 1]], [[0, 1, 2], [0, 2, 3]], process=False)
    fp = _fp(panel)
    assert fp.area == pytest.approx(1.0 * 0.05, rel=0.05)
    x0, y0, x1, y1 = fp.bounds
    assert x1 - x0 == pytest.approx(0.05) and y1 - y0 == pytest.approx(1.0, abs=0.05)


def test_a_turned_vertical_panel_is_widened_too():
    panel = trimesh.Trimesh([[0, 0, 0], [1, 0, 0], [1, 0, 1], [0, 0, 1]], [[0, 1, 2], [0, 2, 3]], process=False)
    panel.apply_transform(trimesh.transformations.rotation_matrix(0.7, [0, 0, 1]))
    assert _fp(panel).area == pytest.approx(1.0 * 0.05, rel=0.05)


# ---------------------------------------------------------------- walls: their cross-section in the band

BAND = (0.05, 1.2)


def test_a_wall_with_a_doorway_is_one_part_whose_band_section_leaves_the_doorway_free():
    wall = wall_with_openings(6.0, 0.1, 2.4, [(2.0, 3.0, 0.0, 2.1)])
    assert len(np.unique(mesh_parts(wall)[1])) == 1  # so the hull of its parts spans the doorway ...
    assert _fp(wall).covers(shapely.box(2.0, 0.0, 3.0, 0.1).buffer(-0.01))
    section = band_section(wall, *BAND, min_width=0.05)  # ... and its band section does not
    exact = shapely.union(shapely.box(0.0, 0.0, 2.0, 0.1), shapely.box(3.0, 0.0, 6.0, 0.1))
    assert section.symmetric_difference(exact).area < 1e-9
    assert section.intersection(shapely.box(2.0, -1.0, 3.0, 1.0)).area == 0


def test_a_window_above_the_band_floor_leaves_the_wall_under_it_solid():
    wall = wall_with_openings(6.0, 0.2, 2.4, [(2.0, 3.0, 0.9, 2.0)])  # sill in the band: the wall blocks below it
    assert band_section(wall, *BAND, min_width=0.05).symmetric_difference(shapely.box(0, 0, 6, 0.2)).area < 1e-9
    assert band_section(wall, 0.95, 1.2, min_width=0.05).area == pytest.approx(5.0 * 0.2)  # a band above the sill


def test_walls_round_a_room_cover_the_walls_not_the_room():
    ring = shapely.box(0, 0, 4, 3).difference(shapely.box(0.1, 0.1, 3.9, 2.9))
    walls = prism(ring, 2.4)
    section = band_section(walls, *BAND, min_width=0.05)
    assert section.symmetric_difference(ring).area < 1e-9


def test_open_and_capless_walls_still_stand():
    sheet = trimesh.Trimesh([[0, 0, 0], [3, 0, 0], [3, 0, 2.4], [0, 0, 2.4]], [[0, 1, 2], [0, 2, 3]], process=False)
    assert band_section(sheet, *BAND, min_width=0.05).area == pytest.approx(3.0 * 0.05)  # widened like a panel
    box = trimesh.creation.box(bounds=[(0, 0, 0), (2, 0.2, 2.4)])
    no_bottom = trimesh.Trimesh(box.vertices, box.faces[box.face_normals[:, 2] > -0.5], process=False)
    assert band_section(no_bottom, *BAND, min_width=0.05).area == pytest.approx(0.4)


def test_a_wall_outside_the_band_has_no_band_section():
    lintel = trimesh.creation.box(bounds=[(0, 0, 2.1), (1, 0.1, 2.4)])
    assert band_section(lintel, *BAND, min_width=0.05).is_empty


# ---------------------------------------------------------------- the step: every object of a scene


def test_object_footprints_cut_walls_in_the_band_and_hull_everything_else():
    """build-scene's footprint step on a wall with a doorway and a box beside it: the wall is its section in the
    band given (the doorway open, the lintel only above it), the box its sampled hull, seeded per instance."""
    wall = wall_with_openings(6.0, 0.1, 2.4, [(2.0, 3.0, 0.0, 2.1)])
    cabinet = trimesh.creation.box(bounds=[(1.0, 1.0, 0.0), (2.0, 1.6, 0.5)])
    scene = inline_scene([("wall", "wall", wall), ("cabinet", "object", cabinet)])
    parts = {i: mesh_parts(m) for i, m in scene.meshes.items()}
    config = BuildSceneConfig()
    fps = object_footprints(scene, parts, BAND, config)
    exact_wall = shapely.union(shapely.box(0.0, 0.0, 2.0, 0.1), shapely.box(3.0, 0.0, 6.0, 0.1))
    assert sorted(fps) == [1, 2] and fps[1].symmetric_difference(exact_wall).area < 1e-9
    assert fps[2].area == pytest.approx(0.6, rel=0.01) and shapely.box(1.0, 1.0, 2.0, 1.6).buffer(1e-9).covers(fps[2])
    above = object_footprints(scene, parts, (2.2, 2.3), config)  # a band through the lintel: the wall is whole
    assert above[1].symmetric_difference(shapely.box(0.0, 0.0, 6.0, 0.1)).area < 1e-9
    assert above[2].equals(fps[2])  # a hull does not depend on the band, and the same seed samples alike
    reseeded = object_footprints(scene, parts, BAND, config.model_copy(update={"seed": 1}))
    assert not reseeded[2].equals(fps[2]) and reseeded[1].equals(fps[1])
