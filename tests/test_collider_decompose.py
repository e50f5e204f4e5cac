"""decompose_meshes: exact parts where the mesh is convex pieces, the mode's methods for the rest, a part budget."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import trimesh

from sagebench.collider_export.coacd_cache import PartCache
from sagebench.collider_export import decompose
from sagebench.collider_export.decompose import WHOLE_MESH_FACTOR, decompose_meshes, plan_pieces
from sagebench.collider_export.quality import measure
from sagebench.scene.furniture import Catalogue
from sagebench.settings.export_usd import ColliderSettings
from tests.test_collider_convex import u_prism
from tests.test_collider_pieces import inside_parts
from tests.test_collider_quality import BAND


def _table() -> trimesh.Trimesh:
    return trimesh.util.concatenate([trimesh.creation.box((1, 1, 0.05)).apply_translation((0, 0, 0.7)),
                                     trimesh.creation.box((0.05, 0.05, 0.7)).apply_translation((0, 0, 0.35))])


def test_mixed_mesh_gets_exact_parts_and_decomposed_pieces(tmp_path):
    table, u = _table(), u_prism()
    mixed = trimesh.util.concatenate([table, u.copy().apply_translation((3, 0, 0))])
    meshes = {name: (m.vertices, m.faces) for name, m in
              {"meshes/table.ply": table, "meshes/mixed.glb": mixed, "meshes/u.obj": u}.items()}
    out = decompose_meshes(meshes, ColliderSettings(mode="fast"), cache=PartCache(tmp_path), band=BAND)
    assert (out["meshes/table.ply"].exact_parts, len(out["meshes/table.ply"].parts)) == (2, 2)
    assert out["meshes/table.ply"].pieces == []
    assert out["meshes/mixed.glb"].exact_parts == 2
    assert [p.method for p in out["meshes/mixed.glb"].pieces] == ["voxel"]  # the U's hull misses the band by 15 cm
    # the U inside `mixed` is moved, so it is a different piece from meshes/u.obj
    assert out["meshes/mixed.glb"].pieces[0].key != out["meshes/u.obj"].pieces[0].key
    two = decompose_meshes(meshes, ColliderSettings(mode="fast"), cache=PartCache(tmp_path / "two"), workers=2,
                           band=BAND)
    for name, mc in out.items():  # meshes split on two processes: the same parts
        assert [(p.vertices.tobytes(), p.faces.tobytes()) for p in mc.parts] == \
            [(p.vertices.tobytes(), p.faces.tobytes()) for p in two[name].parts]


def test_a_split_is_cached_so_the_export_after_a_plan_does_not_split_again(tmp_path, monkeypatch):
    # `sagebench run` plans a scene's pieces in one task and exports it in another: both split every mesh
    table, u = _table(), u_prism()
    mixed = trimesh.util.concatenate([table, u.copy().apply_translation((3, 0, 0))])
    meshes = {name: (m.vertices, m.faces) for name, m in {"table": table, "mixed": mixed, "u": u}.items()}
    settings = ColliderSettings(mode="fast")
    fresh = decompose_meshes(meshes, settings, cache=PartCache(None), band=BAND)
    plan = plan_pieces(meshes, settings, cache=PartCache(tmp_path))

    def split_again(*args, **kwargs):
        raise AssertionError("split again")

    monkeypatch.setattr(decompose, "split_convex", split_again)
    again = plan_pieces(meshes, settings, cache=PartCache(tmp_path))
    assert [(p.name, p.vertices.tobytes(), p.faces.tobytes()) for p in again.jobs] == \
        [(p.name, p.vertices.tobytes(), p.faces.tobytes()) for p in plan.jobs]
    cached = decompose_meshes(meshes, settings, cache=PartCache(tmp_path), band=BAND)
    for name, mc in fresh.items():
        assert mc.exact_parts == cached[name].exact_parts
        assert [(p.vertices.tobytes(), p.faces.tobytes()) for p in mc.parts] == \
            [(p.vertices.tobytes(), p.faces.tobytes()) for p in cached[name].parts]


def _boxes(n: int) -> trimesh.Trimesh:
    """n separate 0.1 m boxes in a row, 0.3 m apart."""
    return trimesh.util.concatenate([trimesh.creation.box((0.1, 0.1, 0.1)).apply_translation((0.3 * i, 0, 0.05))
                                     for i in range(n)])


def test_parts_over_the_budget_are_merged_and_still_cover_the_mesh(tmp_path):
    m = _boxes(10)
    (mc,) = decompose_meshes({"m": (m.vertices, m.faces)}, ColliderSettings(max_parts=4), cache=PartCache(tmp_path),
                             band=BAND).values()
    assert len(mc.parts) == 4 and mc.merged == 6 and mc.exact_parts == 0
    assert inside_parts(m.vertices, mc.parts).all()


def test_exactly_at_the_budget_nothing_is_merged(tmp_path):
    m = _boxes(4)
    (mc,) = decompose_meshes({"m": (m.vertices, m.faces)}, ColliderSettings(max_parts=4), cache=PartCache(tmp_path),
                             band=BAND).values()
    assert (len(mc.parts), mc.merged, mc.exact_parts) == (4, 0, 4)


def test_far_too_many_pieces_make_one_voxel_collider_of_the_whole_mesh(tmp_path):
    n = WHOLE_MESH_FACTOR * 2 + 1
    m = trimesh.util.concatenate([u_prism(0.2, 0.2, 0.05, 0.1).apply_translation((0.3 * i, 0, 0)) for i in range(n)])
    (mc,) = decompose_meshes({"m": (m.vertices, m.faces)}, ColliderSettings(max_parts=2), cache=PartCache(tmp_path),
                             band=BAND).values()
    assert mc.whole and [p.method for p in mc.pieces] == ["voxel"] and len(mc.parts) <= 2
    assert inside_parts(m.vertices, mc.parts, eps=1e-6).all()


FIXTURE = Path(__file__).parent / "fixtures" / "sh3d_cc0"


def _fixture_meshes(*models: str) -> dict[str, trimesh.Trimesh]:
    """The CC0 Sweet Home 3D fixtures (all, or those of these model folders), each scaled to its catalogue
    size and standing on the floor, by entry id."""
    catalogue = Catalogue(FIXTURE)
    return {e.id: catalogue.load_model(e) for e in catalogue.entries
            if not models or Path(e.model).parent.name in models}


def _band_errors(meshes: dict[str, trimesh.Trimesh], settings: ColliderSettings,
                 cache: Path) -> tuple[dict[str, float], int]:
    """Each mesh's collider band error (cm) in these settings, and how many meshes had parts merged."""
    out = decompose_meshes({k: (m.vertices, m.faces) for k, m in meshes.items()}, settings, cache=PartCache(cache),
                           band=BAND)
    for name, mc in out.items():
        assert len(mc.parts) <= settings.max_parts, name
    return ({name: measure(meshes[name].vertices, meshes[name].faces, mc.parts, band=BAND).band_error_cm
             for name, mc in out.items()}, sum(mc.merged > 0 for mc in out.values()))


@pytest.mark.parametrize("max_parts", [32, 8])
def test_real_catalogue_models_stay_within_2_cm_in_the_band_and_within_the_part_budget(tmp_path, max_parts):
    # the eight fixtures: open meshes, concave pieces, one voxelised; the upper corner cabinet's hull fills
    # its L (9 cm over in the band), and its parts merged by bounding boxes alone bridged the L at 8 parts
    errors, merged = _band_errors(_fixture_meshes(), ColliderSettings(mode="balanced", max_parts=max_parts), tmp_path)
    assert {name: e for name, e in errors.items() if e > 2.0} == {}
    assert merged == (5 if max_parts == 8 else 1)


def test_quality_mode_is_within_2_cm_in_the_band_where_balanced_is(tmp_path):
    # CoACD's parts merged to the part budget by bounding boxes alone: the upper corner cabinet 12 cm over in
    # the band (on the bench scene the bed 3 cm at 32 parts) where balanced's voxel parts stayed within 2 cm
    meshes = _fixture_meshes("upperCornerCabinet", "couch2", "chair2", "table")
    balanced, _ = _band_errors(meshes, ColliderSettings(mode="balanced", max_parts=8), tmp_path)
    quality, merged = _band_errors(meshes, ColliderSettings(mode="quality", max_parts=8), tmp_path)
    assert max(balanced.values()) <= 2.0 and merged == 3  # the chair keeps balanced's 5 parts, closer in the band
    assert {name: e for name, e in quality.items() if e > 2.0} == {}


@pytest.mark.parametrize("max_parts", [32, 4])
def test_quality_mode_is_never_farther_off_in_the_band_than_balanced(tmp_path, max_parts):
    # CoACD's four parts of the open Japanese lantern reach 1 cm past it in the band where balanced's hull
    # is exact, and at 4 parts the chair's merged CoACD parts 1.4 cm where balanced's voxel parts reach 1
    meshes = _fixture_meshes("JapaneseLantern", "chair2")
    balanced, _ = _band_errors(meshes, ColliderSettings(mode="balanced", max_parts=max_parts), tmp_path)
    quality, _ = _band_errors(meshes, ColliderSettings(mode="quality", max_parts=max_parts), tmp_path)
    assert {name: (e, balanced[name]) for name, e in quality.items() if e > balanced[name]} == {}


def test_every_part_keeps_within_physx_64_hull_vertices(tmp_path):
    # the demo plant's foliage: an icosphere of 162 vertices, a convex piece of its own (an exact part)
    plant = trimesh.util.concatenate([trimesh.creation.icosphere(subdivisions=2, radius=0.3).apply_translation((0, 0, 0.9)),
                                      trimesh.creation.cylinder(0.15, 0.4, sections=96).apply_translation((0, 0, 0.2))])
    (mc,) = decompose_meshes({"plant": (plant.vertices, plant.faces)}, ColliderSettings(mode="fast"),
                             cache=PartCache(tmp_path), band=BAND).values()
    assert len(mc.parts) == 2 and max(len(p.vertices) for p in mc.parts) == 64


def open_c_sofa() -> trimesh.Trimesh:
    """An artist's open concave piece: a 270-degree C of 0.45..0.6 m radius, 0.7 m tall, three faces missing."""
    import shapely

    from sagebench.importers.interiorgs_structure import slab

    ring = shapely.Point(0, 0).buffer(0.6, 32).difference(shapely.Point(0, 0).buffer(0.45, 32))
    c = slab(ring.difference(shapely.box(0, -0.1, 1, 0.1)), 0.0, 0.7)
    return trimesh.Trimesh(c.vertices, c.faces[3:], process=False)


@pytest.mark.slow  # CoACD three times on one piece (about 20 CPU-s)
def test_a_piece_every_method_of_its_mode_misses_escalates_until_it_fits_the_band(tmp_path):
    # balanced's methods miss it (voxel 3.0 cm, CoACD 3.2 cm in the band): finer CoACD fits it within 2 cm
    c = open_c_sofa()
    band = (0.1, 1.2)
    (mc,) = decompose_meshes({"sofa": (c.vertices, c.faces)}, ColliderSettings(), cache=PartCache(tmp_path),
                             band=band).values()
    (piece,) = mc.pieces
    assert piece.method == "coacd_fine" and piece.band_error_cm <= 2.0
    assert measure(c.vertices, c.faces, mc.parts, band=band).band_error_cm <= 2.0
