"""Colliders of a real-building-style scene (tests/fixtures/concave_house: concave walls, doorways, an ajar door):
the same bytes however busy the machine is, and never a wall collider across a doorway."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from sagebench.collider_export import methods
from sagebench.collider_export.free_floor import FloorMap, covered_free_floor
from sagebench.scene.loader import door_pose, load_scene
from sagebench.settings.export_usd import ColliderSettings, ExportConfig
from sagebench.stages.build_scene import build_scene
from sagebench.stages.export_usd import agent_band, export_usd
from sagebench.topdown.grid_file import read_topdown_grids
from sagebench.ui import SETTINGS

HOUSE = Path(__file__).parent / "fixtures" / "concave_house"
SCENE = "concave_house"
OUTPUTS = ("colliders", "scene.usda", "geometry.usdc", "scene.xml")


@pytest.fixture(scope="module")
def house_run(tmp_path_factory) -> Path:
    """The fixture house built (its map at the default 0.05 m)."""
    run = tmp_path_factory.mktemp("house") / "run"
    SETTINGS.quiet = True
    try:
        build_scene(HOUSE, run)
    finally:
        SETTINGS.quiet = False
    return run


def _fresh(run: Path, tmp_path: Path, name: str) -> Path:
    """A copy of the built run to export into."""
    out = tmp_path / name
    shutil.copytree(run, out)
    return out


def _outputs(run: Path) -> dict[str, bytes]:
    scene = run / "scenes" / SCENE
    files = [p for name in OUTPUTS for p in ([scene / name] if (scene / name).is_file() else (scene / name).rglob("*"))]
    return {str(p.relative_to(scene)): p.read_bytes() for p in sorted(files) if p.is_file()}


def test_a_cold_export_under_two_busy_processes_is_byte_identical_to_one_on_an_idle_machine(house_run, tmp_path):
    """The default mode on a cold cache each time (5 cm voxels keep it cheap): two processes spinning on the
    machine's cores change every method's timing, not its parts (the voxel parts of the 8 m L walls once took
    past the old 10 s budget under load, and the walls fell back to their hulls)."""
    config = ExportConfig(colliders=ColliderSettings(voxel_pitch=0.05))
    idle = _fresh(house_run, tmp_path, "idle")
    export_usd(idle, config=config, cache_dir=tmp_path / "cache-idle")
    busy = _fresh(house_run, tmp_path, "busy")
    spinners = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(2)]
    try:
        (result,) = export_usd(busy, config=config, cache_dir=tmp_path / "cache-busy")
    finally:
        for p in spinners:
            p.kill()
            p.wait()
    assert result.cached_pieces == 0 and result.methods == {"voxel": 5}
    a, b = _outputs(idle), _outputs(busy)
    assert len(a) > 10 and a.keys() == b.keys()
    assert [k for k in a if a[k] != b[k]] == []


def _covered(run: Path) -> dict[int, np.ndarray]:
    """instance id -> the free floor its exported parts cover (covered_free_floor), for objects that cover some."""
    import trimesh

    scene = load_scene(run / "scenes" / SCENE)
    grids = read_topdown_grids(run / "scenes" / SCENE / "topdown.npz")
    floor = FloorMap(grids.occupancy, grids.resolution, grids.origin)
    out = {}
    for obj in scene.spec.objects:
        parts = [trimesh.load(p) for p in sorted((run / "scenes" / SCENE / "colliders").glob(f"*_{obj.instance_id}/*.stl"))]
        from sagebench.collider_export.convex import ConvexPart

        spot = covered_free_floor([ConvexPart(np.asarray(m.vertices), np.asarray(m.faces)) for m in parts],
                                  agent_band(scene.source_dir), floor, 0.02)
        if spot is not None:
            out[obj.instance_id] = spot
    return out


def test_fast_colliders_leave_every_doorway_open(house_run, tmp_path):
    run = _fresh(house_run, tmp_path, "fast")
    export_usd(run, config=ExportConfig(colliders=ColliderSettings(mode="fast")), cache_dir=tmp_path / "cache")
    assert _covered(run) == {}


def test_a_wall_whose_collider_would_close_its_doorway_fails_the_export_naming_it(house_run, tmp_path, monkeypatch,
                                                                                   run_cli):
    """Were `fast` to end at the walls' hulls (as the time budget once made it), the export stops with one line
    naming the first such wall and writes nothing."""
    monkeypatch.setitem(methods.LADDERS, "fast", ("hull",))
    monkeypatch.setitem(methods.ESCALATIONS, "fast", ())
    run = _fresh(house_run, tmp_path, "hulls")
    code, out, err = run_cli("export-usd", run, "--cache-dir", tmp_path / "cache", "--colliders", "fast")
    assert code == 2 and out == ""
    assert err.strip().splitlines()[-1] == (
        "error: wall_1: colliders 333.0 cm off in the agent band cover free floor at (2.12, 1.82) that the object "
        "leaves open (a doorway?): no method of --colliders fast came closer on its piece meshes/wall_south_east.obj "
        "(concave piece 0) (best: hull, 333.0 cm in 1 parts); nothing was written")
    assert not any((run / "scenes" / SCENE / name).exists() for name in OUTPUTS)


def test_the_fixture_doors_stand_where_its_readme_says():
    """The ajar leaf leaves the office a 0.415 m gap at its far jamb (1.5 cm more than a 0.20 m agent needs)."""
    import shapely
    import trimesh

    spec = load_scene(HOUSE).spec
    door = next(o for o in spec.objects if o.kind == "door")
    leaf = trimesh.load(HOUSE / door.mesh).apply_transform(door_pose(door.door))
    outline = shapely.MultiPoint(leaf.vertices[:, :2]).convex_hull
    assert door.door.state == "ajar"
    assert outline.distance(shapely.box(4.0, 5.1, 4.12, 5.8)) == pytest.approx(0.415, abs=1e-4)
