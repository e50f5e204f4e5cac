"""`sagebench import-interiorgs` and InteriorGS folders given to build-scene and run: the round trip synth scene ->
InteriorGS folder (tests/interiorgs_fixture.py, written from the dataset card and SAGE-3D's code) -> import ->
every stage, measured against the mesh-built scene; bad input gets one line, exit 2 and nothing written."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import cv2
import numpy as np
import pytest

from interiorgs_fixture import (
    band_footprint_ious, empty_space_filled, in_box_share, iou, on_grid, turned_scene, volume_iou,
    write_interiorgs_folder, write_messy_folder,
)
from sagebench.gvln.frame import to_sage_xy
from sagebench.scene.assets import CATALOGUE, table
from sagebench.scene.loader import load_scene
from sagebench.splats.ply import read_ply
from sagebench.topdown.raster import Grid
from test_fuzz_inputs import snapshot
from tests.sage_benchmark import sage_semantic_map, sage_to_2d


def _label_of(scene_dir: Path) -> dict[int, int]:
    """Imported instance id -> the mesh scene's (the fixture writes each label's ins_id as the mesh instance id)."""
    report = json.loads((scene_dir / "interiorgs_import.json").read_text())
    return {int(k): int(v["label"]) for k, v in report["instances"].items() if v["label"] is not None}


def _navigable_iou(truth, run_scene: Path) -> float:
    maps = np.load(run_scene / "topdown.npz")
    grid = Grid(tuple(maps["origin"]), float(maps["resolution"]), maps["navigable"].shape)
    td = truth.topdown
    return iou(td.navigable != 0, on_grid(maps["navigable"] != 0, grid, td.grid))


def test_demo_round_trip_matches_the_mesh_scene(interiorgs_demo, interiorgs_imported, tmp_path):
    folder, truth = interiorgs_demo
    imported = load_scene(interiorgs_imported)
    mesh = truth.scene.spec
    assert [(r.id, r.type) for r in imported.spec.rooms] == [(r.id, r.type) for r in mesh.rooms]
    for a, b in zip(imported.spec.rooms, mesh.rooms):
        assert np.allclose(a.polygon, b.polygon, atol=1e-6)
    label_of = _label_of(interiorgs_imported)
    kinds = {o.instance_id: (o.kind, o.door.state if o.door else None) for o in mesh.objects}
    assert {kinds[label_of[o.instance_id]] for o in imported.spec.objects if o.instance_id in label_of} == {
        v for v in kinds.values() if v[0] not in ("wall", "floor", "ceiling")}  # doors keep their states
    assigned = read_ply(interiorgs_imported / "gaussians.ply").instance_id
    assert in_box_share(truth, folder, assigned, label_of) >= 0.95
    assert np.median(band_footprint_ious(truth, imported, label_of)) >= 0.80
    tops_on_legs = {c for c, a in CATALOGUE.items() if a.build is table}  # desks and tables: a knee space under
    category = {o.instance_id: o.category for o in mesh.objects}
    knees = [empty_space_filled(truth.scene.meshes[label_of[i]], imported.meshes[i])
             for i in sorted(label_of) if category[label_of[i]] in tops_on_legs]
    assert len(knees) >= 3 and max(knees) < 0.02  # a hull per object fills 94 % (benchmarks/bench_interiorgs.py)
    # walls, floors and ceilings keep their Gaussians, also where an object's box reaches over them (under a sofa)
    structure = ("wall", "floor", "ceiling")
    was = np.isin(truth.gaussian_ids, [o.instance_id for o in mesh.objects if o.kind in structure])
    now = np.isin(assigned, [o.instance_id for o in imported.spec.objects if o.kind in structure])
    assert (now[was]).mean() > 0.99


def test_every_demo_object_blocks_what_its_mesh_blocks(interiorgs_demo, interiorgs_imported):
    """Against the demo's meshes, object by object: the map cells each imported object blocks in the agent's band
    match its mesh's at IoU 0.8 or more (the floor lamp whose pole shows splats on one face only: 0.75 with a
    square post around the splats, 4 cells where the 3 cm pole touches 3)."""
    truth = interiorgs_demo[1]
    imported = load_scene(interiorgs_imported)
    kind = {o.instance_id: o.kind for o in truth.scene.spec.objects}
    label_of = {i: t for i, t in _label_of(interiorgs_imported).items() if kind[t] == "object"}
    category = {o.instance_id: o.category for o in truth.scene.spec.objects}
    bands = {(category[t], t): b for i, t in label_of.items() for b in band_footprint_ious(truth, imported, {i: t})}
    assert len(bands) == 35 and min(bands.values()) >= 0.8, sorted(bands.items(), key=lambda kv: kv[1])[:3]


@pytest.mark.slow  # about a minute of CPU for the volumes: CI runs it (make test-slow)
def test_demo_objects_are_as_solid_as_their_meshes(interiorgs_demo, interiorgs_imported):
    """Against the demo's meshes, object by object (walls, floors, ceilings, doors and windows aside): the volume
    inside the imported parts matches the volume inside the mesh (a sofa, a pot, a cabinet are solid, not shells
    of their visible faces), and so does what each blocks in the agent's band."""
    truth = interiorgs_demo[1]
    imported = load_scene(interiorgs_imported)
    kind = {o.instance_id: o.kind for o in truth.scene.spec.objects}
    label_of = {i: t for i, t in _label_of(interiorgs_imported).items() if kind[t] == "object"}
    volumes = [volume_iou(truth.scene.meshes[t], imported.meshes[i], step=0.03) for i, t in label_of.items()]
    assert len(volumes) == 42 and np.median(volumes) >= 0.85  # 0.57 on 9b12956
    assert np.median(band_footprint_ious(truth, imported, label_of)) >= 0.95


def test_a_floor_lamps_3_cm_pole_blocks_the_agent_in_mujoco(interiorgs_demo, interiorgs_imported):
    """The demo's floor lamps stand on 3 cm poles, captured by a few splats on the pole's surface and wider than it
    (one lamp's all on one face). Driven past a pole on each of four sides with its edge 1.1 cm from the pole's
    axis (inside the pole), the agent touches the imported lamp: the pole's post is round and lies behind its
    splats (it was a 1.3 cm sliver, then a square around the splats that the agent passed on their far side)."""
    import mujoco

    from sagebench.replay.physics import build_replay_model, replay_one
    from sagebench.topdown.footprints import mesh_parts

    truth = interiorgs_demo[1]
    imported = load_scene(interiorgs_imported)
    category = {o.instance_id: o.category for o in truth.scene.spec.objects}
    lamps = {i: t for i, t in _label_of(interiorgs_imported).items() if category[t] == "floor_lamp"}
    assert len(lamps) == 2
    for iid, tid in lamps.items():
        tris, part = mesh_parts(truth.scene.meshes[tid])
        pieces = [tris[part == k].reshape(-1, 3) for k in range(int(part.max()) + 1)]
        pole = next(v for v in pieces if v[:, 2].min() < 0.5 and v[:, 2].max() > 1.0 and np.ptp(v[:, 0]) < 0.05)
        centre, radius = (pole.min(axis=0) + pole.max(axis=0)) / 2, np.ptp(pole[:, 0]) / 2
        assert radius == pytest.approx(0.015, abs=0.002)
        tris, part = mesh_parts(imported.meshes[iid])
        assets = "".join(f"<mesh name='p{k}' vertex='{' '.join(map(str, np.unique(tris[part == k].reshape(-1, 3), axis=0).ravel()))}'/>"
                         for k in range(int(part.max()) + 1))
        bodies = "".join(f"<body name='lamp_{k}'><geom type='mesh' mesh='p{k}'/></body>" for k in range(int(part.max()) + 1))
        mjcf = (f"<mujoco><asset>{assets}</asset><worldbody><geom type='plane' size='0 0 1'/>{bodies}</worldbody>"
                "</mujoco>")
        model = build_replay_model(mujoco.MjSpec.from_string(mjcf), floor_z=0.0)
        for side in ((0, 1), (0, -1), (1, 0), (-1, 0)):  # the agent's radius is 0.2 m
            past = centre[:2] + np.array(side) * (0.2 + 0.011)
            along = np.array([side[1], -side[0]])
            path = np.array([[*(past - along), 0.0, 0.0], [*(past + along), 0.0, 0.0]])
            rec = replay_one(model, path)
            assert rec.contact.any(), (iid, side, rec.outcome)


def test_build_scene_takes_the_folder_and_the_navigable_map_agrees(interiorgs_demo, run_cli, tmp_path):
    folder, truth = interiorgs_demo
    code, out, err = run_cli("build-scene", folder, "--out", tmp_path / "run")
    assert code == 0, err
    assert out.startswith(f"build-scene {folder.name}: ")
    assert _navigable_iou(truth, tmp_path / "run" / "scenes" / folder.name) >= 0.90


@pytest.mark.slow  # two more full apartments, for CI (make test-slow): the demo's round trip runs in make test
@pytest.mark.parametrize("seed", [1, 2])
def test_other_seeds_round_trip(seed, tmp_path):
    """Two more synth apartments, through the library (maps only, no run): the same bars as the demo's."""
    from sagebench.importers.interiorgs import import_interiorgs, write_imported
    from sagebench.scene.synth import write_synth_scene
    from sagebench.settings.build_scene import BuildSceneConfig
    from sagebench.topdown.builder import compute_topdown

    write_synth_scene(tmp_path / "scene", seed=seed)
    folder = tmp_path / f"0002_00000{seed}"
    truth = write_interiorgs_folder(tmp_path / "scene", folder)
    write_imported(import_interiorgs(folder), tmp_path / "imported")
    imported = load_scene(tmp_path / "imported")
    label_of = _label_of(tmp_path / "imported")
    assert [(r.id, r.type) for r in imported.spec.rooms] == [(r.id, r.type) for r in truth.scene.spec.rooms]
    td = compute_topdown(imported, BuildSceneConfig())
    assert iou(truth.topdown.navigable != 0, on_grid(td.navigable != 0, td.grid, truth.topdown.grid)) >= 0.90
    assert np.median(band_footprint_ious(truth, imported, label_of)) >= 0.80
    assert in_box_share(truth, folder, read_ply(tmp_path / "imported" / "gaussians.ply").instance_id, label_of) >= 0.95


@pytest.mark.slow  # the whole pipeline on the InteriorGS demo: CI runs it; build-scene on the folder is in make test
def test_a_run_config_takes_the_folder_and_validates_every_trajectory(interiorgs_demo, interiorgs_imported, run_cli,
                                                                      tmp_path):
    folder, _ = interiorgs_demo
    shutil.copytree(folder, tmp_path / "igs" / folder.name)
    (tmp_path / "run.toml").write_text('scenes = ["igs/*"]\nout = "out"\nseed = 0\ncache_dir = "cache"\n'
                                       "[gen_trajectories]\nper_scene = 8\n[validate]\nframes_per_scene = 1\n")
    code, out, err = run_cli("-q", "run", tmp_path / "run.toml")
    assert code == 0, out + err
    report = json.loads((tmp_path / "out" / "reports" / folder.name / "report.json").read_text())
    assert report["trajectories"] == 8 and report["passed"] == 8, report
    # the run imported the folder on its own: the same meshes and Gaussians, byte for byte, as import-interiorgs
    built = tmp_path / "out" / "scenes" / folder.name
    for path in [*sorted((interiorgs_imported / "meshes").iterdir()), interiorgs_imported / "gaussians.ply"]:
        assert (built / path.relative_to(interiorgs_imported)).read_bytes() == path.read_bytes(), path.name


def _through_passages(run: Path, per_passage: int = 12) -> list[np.ndarray]:
    """Planned paths [M, 4] (as gen-trajectories plans them) between navigable cells within 1.5 m of each passage
    cell of the run's scene that pass through a passage, one per distinct path."""
    from sagebench.astar.grid_astar import astar
    from sagebench.astar.shortcut import shortcut_indices, waypoints

    maps = np.load(next((run / "scenes").glob("*/topdown.npz")))
    nav, res, origin = maps["navigable"], float(maps["resolution"]), tuple(maps["origin"])
    anchors = {(int(r), int(c)): tuple(a) for (r, c), a in zip(maps["passage_cells"], maps["passage_xy"])}
    free, rng, paths = np.argwhere(nav == 1), np.random.default_rng(0), {}
    for cell in anchors:
        near = free[np.abs(free - cell).max(axis=1) <= 30]
        for a, b in near[rng.integers(len(near), size=(per_passage, 2))]:
            found = astar(nav, tuple(map(int, a)), tuple(map(int, b)), res)
            if found is not None and any(tuple(map(int, c)) in anchors for c in found.cells):
                wps = waypoints(found.cells[shortcut_indices(nav, found.cells)], res, origin, 0.0, anchors)
                paths[wps.tobytes()] = wps
    return list(paths.values())


@pytest.mark.slow  # turned synth apartments through the whole pipeline, a few minutes each: CI runs them
@pytest.mark.parametrize(("seed", "yaw"), [(1, 30), (0, 15)])
def test_every_path_through_a_turned_apartment_s_passages_is_walked(seed, yaw, run_cli, tmp_path):
    """Issue 38: on synth apartments turned off the grid and imported as InteriorGS folders, build-scene opens
    passages whose adjacent cells' anchors lie closer together than the replay's waypoint tolerance (seed 1 at
    30 degrees: 1.5 cm apart near (-1.9, -4.1)). Every trajectory gen-trajectories writes passes validate, and
    every path planned through a passage is walked to its end at the default drive speed and at slower ones
    (`[validate.replay] max_speed`): at 0.6 and 0.7 m/s 21 and 26 of seed 1's 68 stalled there before the
    replay drove to a turn command out of reach (goal_not_reached, incomplete)."""
    from sagebench.replay.physics import replay_batch
    from sagebench.replay.scene_model import open_replay_model
    from sagebench.scene.synth import write_synth_scene
    from sagebench.settings.shared import ReplayConfig
    from sagebench.validation.checks import judge

    write_synth_scene(tmp_path / "synth", seed=seed)
    folder = tmp_path / f"0003_{seed:06d}"
    write_interiorgs_folder(turned_scene(tmp_path / "synth", tmp_path / "turned", yaw), folder)
    run = tmp_path / "run"
    for args in (("build-scene", folder, "--out", run), ("gen-trajectories", run, "--per-scene", "40"),
                 ("export-usd", run, "--cache-dir", tmp_path / "cache", "--colliders", "fast")):
        code, _, err = run_cli("-q", *args)
        assert code == 0, err
    code, out, err = run_cli("validate", run)
    assert code == 0 and "40/40 trajectories pass" in out, out + err
    planned = _through_passages(run)
    assert any((np.linalg.norm(np.diff(p[:, :2], axis=0), axis=1) < ReplayConfig().waypoint_tolerance).any()
               for p in planned)  # the case: two waypoints closer than the tolerance
    for speed in (0.6, 0.7, ReplayConfig().max_speed):
        rm = open_replay_model(run, folder.name, replay=ReplayConfig(max_speed=speed))
        paths = [np.column_stack([p[:, :2], np.full(len(p), rm.floor_z), p[:, 3]]) for p in planned]
        failed = [(judge(rec, p, p[-1, :3], goal_radius=0.5, geodesic_distance=1.0, timestep=rm.timestep).reasons,
                   p[:, :2].round(3).tolist()) for p, rec in zip(paths, replay_batch(rm, paths))]
        assert not [f for f in failed if f[0]], (speed, [f for f in failed if f[0]][:2])


def test_collision_usd_meshes_replace_the_surfaces(interiorgs_demo, run_cli, tmp_path):
    """SAGE-3D's collision file turned by 180 degrees about Z (as its USD template places it) is found in the
    scene's own frame; each object then has the mesh of its own collision prim."""
    from interiorgs_fixture import collision_usd

    folder, truth = interiorgs_demo
    collision_usd(truth.scene, tmp_path / "839920_collision.usd", turned=True)
    code, out, err = run_cli("import-interiorgs", folder, "--out", tmp_path / "scene",
                             "--collision-usd", tmp_path / "839920_collision.usd")
    assert code == 0, err
    report = json.loads((tmp_path / "scene" / "interiorgs_import.json").read_text())
    objects = [o for o in truth.scene.spec.objects if o.kind not in ("wall", "floor", "ceiling")]
    assert report["collision_meshes"]["turned_180_about_z"] is True
    assert report["collision_meshes"]["objects"] == len(objects)
    imported = load_scene(tmp_path / "scene")
    for iid, tid in _label_of(tmp_path / "scene").items():
        assert np.allclose(imported.meshes[iid].bounds, truth.scene.meshes[tid].bounds, atol=1e-6)


def _broken(folder: Path, tmp_path: Path, name: str, edit) -> Path:
    dst = tmp_path / "0001_broken"
    shutil.copytree(folder, dst)
    edit(dst / name) if name else edit(dst)
    return dst


def _labels_edit(fn):
    def edit(path: Path) -> None:
        labels = json.loads(path.read_text())
        fn(labels)
        path.write_text(json.dumps(labels))
    return edit


def _ins_id_of_5000_digits(path: Path) -> None:
    labels = json.loads(path.read_text())
    labels[3]["ins_id"] = "@"
    path.write_text(json.dumps(labels).replace('"@"', "9" * 5000))  # json.dumps cannot write such an int itself


def _ply_chunk_edit(fn):
    """An edit of the compressed PLY's chunk table (float32 bounds of 256 Gaussians each) by `fn(table)`."""
    def edit(path: Path) -> None:
        from sagebench.splats.ply import _parse_header

        data = bytearray(path.read_bytes())
        elements, body = _parse_header(bytes(data), path)
        chunk = elements[0]
        end = body + chunk.count * chunk.dtype.itemsize
        table = np.frombuffer(bytes(data[body:end]), dtype=chunk.dtype).copy()
        fn(table)
        data[body:end] = table.tobytes()
        path.write_bytes(bytes(data))
    return edit


def _box_corners(size: tuple[float, float, float]) -> list[dict]:
    """The 8 corners of an axis-aligned box of `size` (m) at the origin, bottom face first."""
    x, y, z = size
    return [{"x": a, "y": b, "z": c} for c in (0.0, z) for a, b in ((0.0, 0.0), (x, 0.0), (x, y), (0.0, y))]


def _occupancy_edit(**changes):
    def edit(path: Path) -> None:
        path.write_text(json.dumps({**json.loads(path.read_text()), **changes}))
    return edit


@pytest.mark.filterwarnings("error::RuntimeWarning")  # a numpy warning before the error line fails the row
@pytest.mark.parametrize(("name", "edit", "message"), [
    ("labels.json", _labels_edit(lambda labels: labels[-1].__setitem__("bounding_box", _box_corners((20000, 1, 1)))),
     "{d}/labels.json: [81].bounding_box: a box of 1 x 20000 x 1 m is 4.2e+08 voxels at --voxel 0.04 m, over the "
     "budget of 3.4e+07 voxels per object"),
    ("labels.json", lambda p: p.write_text("[]"),
     "{d}/labels.json: holds no labels: an InteriorGS scene labels each of its objects"),
    ("labels.json", _labels_edit(lambda labels: [lab.__setitem__("ins_id", "7") for lab in labels]),
     "{d}/labels.json: [1].ins_id: all 82 labels have ins_id '7': each instance needs its own"),
    ("occupancy.json", _occupancy_edit(min=[1e308, -0.2, 0.0], max=None),
     "{d}/occupancy.json: min[0]: Input should be less than or equal to 1000000"),
    ("3dgs_compressed.ply", _ply_chunk_edit(lambda t: t["min_x"].__setitem__(3, np.float32("inf"))),
     "{d}/3dgs_compressed.ply: vertex: Gaussian 768 has a non-finite position (256 of 290192 do)"),
    ("3dgs_compressed.ply", _ply_chunk_edit(lambda t: t["max_scale_x"].__setitem__(3, 3e38)),
     "{d}/3dgs_compressed.ply: vertex: Gaussian 771 has a scale over e^50 m (149 of 290192 do)"),

    ("labels.json", _ins_id_of_5000_digits,
     "{d}/labels.json: malformed JSON: Exceeds the limit (4300 digits) for integer string conversion: value has 5000 "
     "digits"),
    ("labels.json", _labels_edit(lambda labels: labels[3].__setitem__("label", "x" * 100_000)),
     "{d}/labels.json: [3].label: String should have at most 128 characters"),
    ("labels.json", _labels_edit(lambda labels: labels[3].__setitem__("label", "chair\nleg")),
     "{d}/labels.json: [3].label: String should match pattern '^[^\\x00-\\x1f\\x7f]*$'"),
    (None, lambda d: (d / "labels.json").unlink(),
     "{d}: missing labels.json (an InteriorGS scene folder holds 3dgs_compressed.ply, labels.json, structure.json, "
     "occupancy.png, occupancy.json)"),
    ("3dgs_compressed.ply", lambda p: p.write_bytes(b"ply\nformat binary_little_endian 1.0\nelement vertex 1\n"
                                                    b"property float a\nproperty float b\nend_header\n" + bytes(8)),
     "{d}/3dgs_compressed.ply: neither the INRIA 3DGS layout (x, y, z, f_dc_0, ...) nor the compressed SuperSplat "
     "layout (a 'chunk' element and packed_position, ...): vertex has a, b"),
    ("labels.json", _labels_edit(lambda labels: labels[3]["bounding_box"].pop()),
     "{d}/labels.json: [3].bounding_box: 7 corners; an oriented box has 8"),
    ("labels.json", _labels_edit(lambda labels: labels[3].__setitem__("bounding_box", [labels[3]["bounding_box"][0]] * 8)),
     "{d}/labels.json: [3].bounding_box: zero volume: two corners are 0 m apart"),
    ("structure.json", lambda p: p.write_text(json.dumps({**json.loads(p.read_text()), "rooms": []})),
     "{d}/structure.json: rooms: no rooms: the floor plan needs at least one room profile"),
    ("occupancy.json", lambda p: p.write_text(json.dumps({**json.loads(p.read_text()), "scale": 0.1})),
     "{d}/occupancy.json: scale: min..max at scale 0.1 m/px spans 119.5 x 81.5 px but occupancy.png is 239 x 163 px"),
])
def test_bad_folders_get_one_line_and_nothing_is_written(interiorgs_demo, run_cli, tmp_path, name, edit, message):
    folder = _broken(interiorgs_demo[0], tmp_path, name, edit)
    before = snapshot(tmp_path)
    code, out, err = run_cli("import-interiorgs", folder, "--out", tmp_path / "out")
    assert (code, out) == (2, "")
    assert err == f"error: {message.format(d=folder)}\n"
    assert not (tmp_path / "out").exists() and snapshot(tmp_path) == before


def test_a_voxel_too_fine_for_the_budget_is_refused_before_anything_is_allocated(interiorgs_demo, run_cli, tmp_path):
    before = snapshot(tmp_path)
    code, out, err = run_cli("import-interiorgs", interiorgs_demo[0], "--out", tmp_path / "out", "--voxel", "0.0001")
    assert (code, out) == (2, "")
    assert err == ("error: --voxel: 0.0001 m makes 3.4e+12 voxels of the 1.68 x 2.41 x 0.85 m box of labels.json [40] "
                   "(sofa), over the budget of 3.4e+07 voxels per object; use --voxel 0.0048 or more\n")
    assert snapshot(tmp_path) == before


def test_a_repeated_ins_id_is_renamed_and_a_door_on_no_wall_is_a_warning(interiorgs_demo, run_cli, tmp_path):
    def zero_length_wall_0(path: Path) -> None:  # the wall that holds holes[0], a DOOR, shrunk to a point
        structure = json.loads(path.read_text())
        structure["walls"][0]["location"][1] = structure["walls"][0]["location"][0]
        path.write_text(json.dumps(structure))

    folder = _broken(interiorgs_demo[0], tmp_path, "structure.json", zero_length_wall_0)
    _labels_edit(lambda labels: labels[81].__setitem__("ins_id", labels[80]["ins_id"]))(folder / "labels.json")
    code, out, err = run_cli("import-interiorgs", folder, "--out", tmp_path / "out")
    assert code == 0, err
    first = json.loads((interiorgs_demo[0] / "labels.json").read_text())[80]["ins_id"]
    warnings = [line for line in err.splitlines() if line.startswith("warning: ")]
    assert warnings == [
        f"warning: 1 labels repeat an earlier label's ins_id and are renamed, so that each ins_id names one instance: "
        f"labels.json [81] '{first}' -> '{first}#2'",
        "warning: 1 openings lie on no wall, so no wall is cut for them (walls of length 0: walls[0]): structure.json "
        "holes[0] (DOOR)"]
    report = json.loads((tmp_path / "out" / "interiorgs_import.json").read_text())
    labels = [v["label"] for v in report["instances"].values() if v["label"] is not None]
    assert len(labels) == len(set(labels)) and f"{first}#2" in labels
    assert report["openings_on_no_wall"] == [0]


def test_labels_holding_no_gaussians_and_a_disagreeing_occupancy_map_are_warnings(interiorgs_demo, run_cli, tmp_path):
    last = len(json.loads((interiorgs_demo[0] / "labels.json").read_text())) - 1  # furniture comes last

    def far_away(labels: list) -> None:  # two boxes moved 100 m off: nothing of the scene is in them
        for k in (last - 2, last):
            for corner in labels[k]["bounding_box"]:
                corner["x"] += 100.0

    folder = _broken(interiorgs_demo[0], tmp_path, "labels.json", _labels_edit(far_away))
    image = cv2.imread(str(folder / "occupancy.png"), cv2.IMREAD_GRAYSCALE)
    cv2.imwrite(str(folder / "occupancy.png"), np.full_like(image, 255))  # all free: walls and furniture too
    code, out, err = run_cli("import-interiorgs", folder, "--out", tmp_path / "out")
    assert code == 0
    assert out.startswith("import-interiorgs 0001_broken: 54 objects from 82 labels, 5 rooms, 16 walls, 7 doors, ")
    assert f"warning: 2 labels hold no Gaussians and are left out: labels.json [{last - 2}], [{last}]\n" in err
    report = json.loads((tmp_path / "out" / "interiorgs_import.json").read_text())
    assert report["labels_without_gaussians"] == [last - 2, last]
    iou = report["occupancy_iou"]
    assert iou < 0.8 and f"agreement {iou:.3f} IoU" in out
    assert (f"warning: 0001_broken: occupancy.png and the imported geometry agree on {iou:.0%} of the free floor "
            f"(IoU, under 80%); see occupancy_check.png\n") in err
    picture = cv2.imread(str(tmp_path / "out" / "occupancy_check.png"))
    assert (picture == (60, 90, 220)[::-1]).all(axis=2).any()  # blue: free only in occupancy.png


@pytest.fixture(scope="module")
def messy_import(interiorgs_demo, tmp_path_factory):
    """The demo folder with issue 38's four messes (5 % floaters, 1 cm jitter, the bed's label removed, the last
    label given the ins_id of the one before it), imported once: (Mess, ImportResult). Do not modify it."""
    from sagebench.stages.import_interiorgs import import_interiorgs_scene

    folder, truth = interiorgs_demo
    root = tmp_path_factory.mktemp("messy")
    mess = write_messy_folder(folder, root / "0001_messy", truth)
    return mess, import_interiorgs_scene(root / "0001_messy", root / "scene")


def test_a_messy_folder_keeps_an_unlabelled_bed_blocked(interiorgs_demo, interiorgs_imported, messy_import):
    """All four messes at once: the bed still blocks the floor, the navigable map stays that of the clean import,
    and no trajectory starts or ends at the unlabelled obstacle."""
    from sagebench.episodes.targets import scene_targets
    from sagebench.settings.build_scene import BuildSceneConfig
    from sagebench.topdown.builder import compute_topdown

    truth = interiorgs_demo[1]
    mess, result = messy_import
    maps = {}
    for key, scene_dir in (("clean", interiorgs_imported), ("messy", result.out_dir)):
        td = compute_topdown(load_scene(scene_dir), BuildSceneConfig())
        maps[key] = on_grid(td.navigable != 0, td.grid, truth.topdown.grid)
    unnamed = {i.instance_id for i in td.semantic.instances if i.category == "unlabelled"}
    targets, names = scene_targets(load_scene(result.out_dir).spec, td.semantic)
    assert unnamed and not unnamed & {t.instance_id for t in targets}
    assert not any("unlabelled" in n for n in names.values())
    bed = truth.topdown.instance == mess.removed
    assert bed.sum() > 1000 and 1 - maps["messy"][bed].mean() >= 0.95  # 16 % stay blocked without the evidence
    assert iou(maps["clean"], maps["messy"]) >= 0.97  # 0.88 without dropping the floaters
    picture = cv2.imread(str(result.out_dir / "occupancy_check.png"))
    assert (picture == (240, 150, 30)[::-1]).all(axis=2).sum() > 1000  # the bed in orange


def test_a_messy_import_names_each_of_its_four_problems(interiorgs_imported, messy_import):
    """The summary counts the floaters dropped, gives the unlabelled obstacle's area and the surface noise; the
    warnings name the renamed ins_id, the unlabelled obstacle and the noise, each once."""
    mess, result = messy_import
    report, summary = result.report, result.summary()
    assert report["floaters_dropped"] >= 0.7 * mess.floaters
    assert f" Gaussians ({report['floaters_dropped']:,} floaters dropped; " in summary
    (name, found), = report["unlabelled"].items()
    assert 3.0 <= found["area_m2"] <= 3.8  # the bed is 1.6 x 2.05 m
    assert f"unlabelled obstacles: 1 ({found['area_m2']:.2f} m^2)" in summary
    noise = report["surface_noise_m"]
    assert f"surface noise {noise * 100:.2f} cm, " in summary
    index, ins_id = mess.duplicated
    assert list(result.warnings) == [
        f"1 labels repeat an earlier label's ins_id and are renamed, so that each ins_id names one instance: "
        f"labels.json [{index}] '{ins_id}' -> '{ins_id}#2'",
        f"0001_messy: {found['area_m2']:.2f} m^2 of floor that no label explains (over 0.25 m^2) is blocked as "
        f"unlabelled obstacles: {name}; see occupancy_check.png (orange)",
        f"0001_messy: the Gaussians on walls and floor scatter {noise * 100:.2f} cm about their planes (robust "
        "standard deviation, over 0.5 cm): positional noise that widens every obstacle and wall of the maps by "
        "about as much"]
    labels = [v["label"] for v in report["instances"].values() if v["label"] is not None]
    assert len(labels) == len(set(labels)) and f"{ins_id}#2" in labels
    assert not json.loads((interiorgs_imported / "interiorgs_import.json").read_text())["unlabelled"]


def test_the_surface_noise_reads_0_clean_and_the_jitter_of_a_jittered_capture(interiorgs_imported, messy_import):
    """How far the wall and floor Gaussians scatter about their planes: 0 for Gaussians sampled on the meshes,
    the 1 cm of normal jitter per axis (within 20 %) for the messy folder's."""
    clean = json.loads((interiorgs_imported / "interiorgs_import.json").read_text())["surface_noise_m"]
    assert clean < 0.0005
    assert 0.008 <= messy_import[1].report["surface_noise_m"] <= 0.012


def test_out_holding_other_files_is_refused(interiorgs_demo, run_cli, tmp_path):
    (tmp_path / "out").mkdir()
    (tmp_path / "out" / "notes.txt").write_text("mine")
    code, _, err = run_cli("import-interiorgs", interiorgs_demo[0], "--out", tmp_path / "out")
    assert code == 2
    assert err == (f"error: {tmp_path / 'out'}: --out: is not empty and not a scene written by `sagebench "
                   "import-interiorgs`; choose another --out (or --force to replace it)\n")
    assert (tmp_path / "out" / "notes.txt").read_text() == "mine"


def test_the_import_records_where_sage_s_rounded_map_bounds_put_its_3d_frame(interiorgs_demo, interiorgs_imported):
    folder, _ = interiorgs_demo
    meta = json.loads((folder / "occupancy.json").read_text())
    png = cv2.imread(str(folder / "occupancy.png"), cv2.IMREAD_GRAYSCALE)
    start, scale = np.array(meta["min"][:2]), meta["scale"]
    smap = sage_semantic_map(json.loads((folder / "labels.json").read_text()), png, tuple(start), scale)
    offset = json.loads((interiorgs_imported / "interiorgs_import.json").read_text())["sage_offset_m"]
    assert load_scene(interiorgs_imported).spec.sage_offset == pytest.approx(offset, abs=0)
    world = np.array([0.5, -1.0])
    # SAGE's evaluator takes the exported point back to its 2D map: the world turned about the grid's centre
    turned = 2 * start + np.array(png.shape[::-1]) * scale - world
    assert sage_to_2d(list(to_sage_xy(world, tuple(offset))), smap) == pytest.approx(turned, abs=1e-9)
