"""Narrow passages on the exact geometry: the concave house's office, 1.5 cm wider than the agent needs behind an
ajar door, is reachable whatever the grid, paths through it keep to the geometry, and their replays pass."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import shapely
import trimesh

from inline_scene import inline_scene

from sagebench.scene.loader import load_scene
from sagebench.topdown.builder import BuildSceneConfig, compute_topdown
from sagebench.topdown.footprints import mesh_parts
from sagebench.topdown.occupancy import scene_occupancy
from sagebench.topdown.passages import MARGIN, PASSAGE, _best_points, _clearance_field, _fitting, open_passages
from sagebench.topdown.raster import Grid
from sagebench.topdown.regions import label_regions

HOUSE = Path(__file__).parent / "fixtures" / "concave_house"
RADIUS = BuildSceneConfig().agent.radius


def _sections(scene) -> shapely.Geometry:
    """The walls and the door leaf in plan, as tests/fixtures/concave_house/make_house.py lays them out (its
    docstring), with the leaf turned by the scene's own ajar angle: the exact obstacles in the agent's band."""
    door = next(o.door for o in scene.spec.objects if o.door is not None)
    leaf = shapely.affinity.rotate(shapely.box(4.08, 4.2, 4.12, 5.1), -door.ajar_deg, origin=(4.12, 4.2))
    return shapely.union_all([
        shapely.box(0, 0, 8, 0.2), shapely.box(7.8, 0, 8, 6), shapely.box(0, 5.8, 8, 6), shapely.box(0, 0, 0.2, 6),
        shapely.box(0.2, 3.4, 7.8, 3.52).difference(shapely.box(1.5, 3.4, 2.4, 3.52)),
        shapely.box(4.88, 0.2, 5.0, 3.4).difference(shapely.box(4.88, 1.0, 5.0, 1.9)),
        shapely.box(4.0, 3.52, 4.12, 5.8).difference(shapely.box(4.0, 4.2, 4.12, 5.1)), leaf])


@pytest.mark.parametrize("resolution", [0.04, 0.05, 0.06])
def test_the_office_is_reachable_whatever_the_grid_and_each_anchor_clears_the_geometry(resolution):
    scene = load_scene(HOUSE)
    td = compute_topdown(scene, BuildSceneConfig(resolution=resolution))
    assert all(r.reachable for r in td.semantic.rooms), [r.room_id for r in td.semantic.rooms if not r.reachable]
    cells, anchors = td.passages.cells, td.passages.anchors
    assert len(cells) >= 2 and (td.navigable[cells[:, 0], cells[:, 1]] == PASSAGE).all()
    assert np.count_nonzero(td.navigable == PASSAGE) == len(cells)
    obstacles = _sections(scene)
    clearance = shapely.distance(obstacles, shapely.points(anchors))
    assert clearance.min() >= RADIUS + MARGIN - 1e-4, clearance.min()
    lo = np.asarray(td.grid.origin) + cells[:, ::-1] * resolution  # each anchor lies in its own cell
    assert ((anchors >= lo - 1e-9) & (anchors <= lo + resolution + 1e-9)).all()


def test_a_map_in_one_piece_is_left_as_it_is():
    nav = np.zeros((20, 20), dtype=bool)
    nav[5:15, 5:15] = True
    occupied = ~np.pad(np.ones((18, 18), dtype=bool), 1)
    out, passages = open_passages(nav, occupied, np.zeros((0, 9, 2)), shapely.box(0.05, 0.05, 0.95, 0.95),
                                  Grid((0.0, 0.0), 0.05, (20, 20)), RADIUS)
    assert np.array_equal(out, nav.astype(np.uint8)) and len(passages.cells) == 0


def _two_blocks(gap: tuple[float, float]):
    """Two blocks across a 2 m room, a gap between x = gap[0] and gap[1]: their occupancy, plan and grid."""
    blocks = [shapely.box(0.0, 0.96, gap[0], 1.06), shapely.box(gap[1], 0.96, 2.0, 1.06)]
    scene = inline_scene([("block", "object", trimesh.creation.box(bounds=[(*b.bounds[:2], 0), (*b.bounds[2:], 2.4)]))
                          for b in blocks])
    plan, grid = shapely.box(0, 0, 2, 2), Grid((-0.1, -0.1), 0.05, (44, 44))
    parts = {i: mesh_parts(m) for i, m in scene.meshes.items()}
    return blocks, scene_occupancy(scene.spec.objects, parts, plan, grid, (0.05, 1.2), RADIUS), plan, grid


@pytest.mark.parametrize("gap, opened", [((0.81, 1.224), True), ((0.81, 1.195), False)])
def test_a_passage_opens_between_two_footprints_only_where_the_agent_fits(gap, opened):
    """Two blocks across a 2 m room leave a gap that holds no navigable cell centre. At 0.414 m, 1 cm wider than
    the agent needs (2 x (radius + MARGIN) = 0.404 m), a passage opens: one region after, each anchor clearing
    both blocks. At 0.385 m (7.5 mm short of the radius on each side) the rooms stay apart."""
    blocks, occ, plan, grid = _two_blocks(gap)
    assert label_regions(occ.navigable)[1] == 2  # the cells' centres leave the gap shut
    out, passages = open_passages(occ.navigable, occ.occupied, occ.band_polys, plan, grid, RADIUS)
    assert label_regions(out)[1] == (1 if opened else 2) and bool(len(passages.cells)) is opened
    assert np.count_nonzero(out == PASSAGE) == len(passages.cells)
    if opened:
        clearance = shapely.distance(shapely.union_all(blocks), shapely.points(passages.anchors))
        assert clearance.min() >= RADIUS + MARGIN - 1e-4, clearance.min()


@pytest.mark.parametrize("start", [0.8, 0.8133, 0.8271])
@pytest.mark.parametrize("width", [0.4031, 0.4046, 0.4063, 0.4137])
def test_a_cell_settled_early_is_decided_as_the_full_search_decides_it(start, width):
    """build-scene searches a left-out cell only until it is known whether the agent fits there (issue 40): on
    gaps around the agent's width (2 x (radius + MARGIN) = 0.404 m), their middle line off the search's points,
    every free cell is decided as the full search decides it, and a cell's best point and clearance do not
    depend on which other cells are searched with it (the passage's anchors are searched on their own)."""
    _, occ, plan, grid = _two_blocks((start, start + width))
    rc = np.argwhere(~occ.occupied & ~occ.navigable)
    clearance = _clearance_field(occ.occupied, occ.band_polys, plan, grid)
    points, best = _best_points(rc, clearance, grid)
    need = RADIUS + MARGIN
    xy = np.asarray(grid.origin) + (rc[:, ::-1] + 0.5) * grid.resolution
    in_gap = (xy[:, 0] > start) & (xy[:, 0] < start + width) & (xy[:, 1] > 0.96) & (xy[:, 1] < 1.06)
    assert in_gap.any() and bool((best[in_gap] >= need).any()) is (width >= 2 * need)
    assert np.array_equal(_fitting(rc, clearance, grid, need), best >= need)
    some = np.flatnonzero(best >= need - 0.01)
    assert np.array_equal(_best_points(rc[some], clearance, grid)[0], points[some])


def test_trajectories_through_the_passage_keep_to_the_geometry_and_replay_clean(tmp_path, run_cli):
    """gen-trajectories plans into the office through the passage; every reference segment keeps the agent's
    radius from the walls and the leaf, less the bend of a one-cell step (3 mm); validate replays all of them."""
    import pyarrow.parquet as pq

    run = tmp_path / "run"
    for args in (("build-scene", HOUSE, "--out", run), ("gen-trajectories", run, "--per-scene", "16"),
                 ("export-usd", run, "--cache-dir", tmp_path / "cache", "--colliders", "fast")):
        code, _, err = run_cli("-q", *args)
        assert code == 0, err
    rows = pq.read_table(sorted((run / "episodes" / "concave_house").rglob("*.parquet"))).to_pylist()
    through = [r for r in rows if "office" in (r["start_room"], r["goal_room"])]
    assert through
    obstacles = _sections(load_scene(HOUSE))
    for row in rows:
        path = np.array(row["reference_path"])[:, :2]
        segments = shapely.linestrings(np.stack([path[:-1], path[1:]], axis=1))
        assert shapely.distance(obstacles, segments).min() >= RADIUS - 0.003, row["trajectory_id"]
    code, out, err = run_cli("validate", run)
    assert code == 0 and "16/16 trajectories pass" in out, out + err
