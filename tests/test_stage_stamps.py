"""A run made stage by stage (build-scene, gen-trajectories, export-usd, validate, import-sage-episodes; no
manifest) has the stamps `sagebench run` writes, so validate, verify and every later stage catch a deleted, changed
or stray file as they do on a run that `run` made, and `run` skips the stages made with its settings."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
from test_fuzz_safety import _flip_geodesic, refused

SCENE_OPTIONS = ["--object-density", "20", "--structure-density", "5"]  # few Gaussians: cheap
STAGE_COMMANDS = [["gen-trajectories", "--per-scene", "8", "--min-geodesic", "1.0"],
                  ["export-usd", "--colliders", "fast"],
                  ["validate", "--frames-per-scene", "0"]]
TOML = ('scenes = ["{scene}"]\nout = "{out}"\nseed = 0\ncache_dir = "{cache}"\n'
        "[build_scene.splats]\nobject_density = 20.0\nstructure_density = 5.0\n"
        "[gen_trajectories]\nper_scene = 8\nmin_geodesic_m = 1.0\n[export_usd.colliders]\nmode = \"fast\"\n"
        "[validate]\nframes_per_scene = 0\n")
STAGES = ("build_scene", "gen_trajectories", "export_usd", "validate")


def _cli(*args) -> None:
    from sagebench.cli import main

    with pytest.raises(SystemExit) as done:
        main(["-q", *map(str, args)])
    assert done.value.code in (0, None), args


@pytest.fixture(scope="module")
def staged_run(tiny_scene, tmp_path_factory) -> Path:
    """The tiny scene through the four stage commands, one by one, with the settings of TOML. Read-only: copy it."""
    root = tmp_path_factory.mktemp("staged")
    run = root / "run"
    _cli("build-scene", tiny_scene, "--out", run, *SCENE_OPTIONS)
    for command, *options in STAGE_COMMANDS:
        cache = ["--cache-dir", root / "cache"] if command == "export-usd" else []
        _cli(command, run, *options, *cache)
    assert len(list((run / "episodes" / "tiny").glob("part-*.parquet"))) >= 2
    assert not (run / "manifest.json").exists()
    return run


def _copy(run: Path, to: Path) -> Path:
    shutil.copytree(run, to)
    return to


def _shard(run: Path) -> Path:
    return run / "episodes" / "tiny" / "part-train-00000.parquet"


GEN = "gen-trajectories wrote it (its stamp .stamps/tiny/gen_trajectories.json lists it)"
VALIDATE_CASES = {  # damage to a copy of the staged run -> the file validate names, and why
    "shard-deleted": (lambda run: _shard(run).unlink(), "part-train-00000.parquet",
                      f"missing: {GEN}; run gen-trajectories again"),
    "shard-value-flipped": (_flip_geodesic, "part-train-00000.parquet",
                            "changed since gen-trajectories wrote it (its stamp .stamps/tiny/gen_trajectories.json "
                            "records another sha256); run gen-trajectories again"),
    "stray-shard": (lambda run: shutil.copy(_shard(run), run / "episodes" / "tiny" / "part-train-00009.parquet"),
                    "part-train-00009.parquet",
                    "not written by gen-trajectories: its stamp .stamps/tiny/gen_trajectories.json does not list it; "
                    "remove it, or run gen-trajectories again"),
}


@pytest.mark.parametrize("case", list(VALIDATE_CASES))
def test_validate_checks_a_run_made_stage_by_stage_against_its_stamps(case, staged_run, run_cli, tmp_path):
    run = _copy(staged_run, tmp_path / "run")
    damage, name, why = VALIDATE_CASES[case]
    damage(run)
    line = refused(run_cli, ["validate", run, "--frames-per-scene", "0"], tmp_path, why)
    assert line == f"error: {run / 'episodes' / 'tiny' / name}: {why}"


def _flip_a_header_byte(path: Path) -> None:
    """A byte of the zip's local header (the first member's modification time): np.load reads the maps as before,
    only the file's hash tells."""
    data = bytearray(path.read_bytes())
    data[10] ^= 0x01
    path.write_bytes(bytes(data))


@pytest.mark.parametrize("command", [c[0] for c in STAGE_COMMANDS])
def test_a_stage_refuses_an_input_changed_since_the_stage_that_wrote_it(command, staged_run, run_cli, tmp_path):
    run = _copy(staged_run, tmp_path / "run")
    topdown = run / "scenes" / "tiny" / "topdown.npz"
    _flip_a_header_byte(topdown)
    line = refused(run_cli, [command, run], tmp_path, "topdown.npz")
    assert line == (f"error: {topdown}: changed since build-scene wrote it (its stamp .stamps/tiny/build_scene.json "
                    "records another sha256); run build-scene again")


def test_verify_checks_a_run_made_stage_by_stage_against_its_stamps(staged_run, run_cli, tmp_path):
    run = _copy(staged_run, tmp_path / "run")
    assert run_cli("verify", run) == (0, f"ok: every file of {run} matches the stamps of the stages that wrote them\n",
                                      "")
    _shard(run).unlink()
    (run / "scenes" / "tiny" / "colliders" / "extra.stl").write_bytes(b"solid x\nendsolid x\n")
    code, out, _ = run_cli("verify", run)
    assert code == 1
    assert out.splitlines() == [
        f"broken: episodes/tiny/part-train-00000.parquet: missing: {GEN}; run gen-trajectories again",
        "broken: scenes/tiny/colliders/extra.stl: not written by export-usd: its stamp .stamps/tiny/export_usd.json "
        "does not list it; remove it, or run export-usd again"]


def _stamps(run: Path) -> dict[str, dict]:
    return {stage: json.loads((run / ".stamps" / "tiny" / f"{stage}.json").read_text()) for stage in STAGES}


def test_stage_commands_stamp_what_run_would_and_run_skips_them(staged_run, tiny_scene, run_cli, tmp_path):
    made = tmp_path / "made"
    config = tmp_path / "made.toml"
    config.write_text(TOML.format(scene=tiny_scene, out=made, cache=tmp_path / "cache"))
    assert run_cli("run", config)[0] == 0
    by_run, by_stage = _stamps(made), _stamps(staged_run)
    assert {s: (v["outputs"], v["key"]) for s, v in by_stage.items()} == {
        s: (v["outputs"], v["key"]) for s, v in by_run.items()}
    run = _copy(staged_run, tmp_path / "run")
    config.write_text(TOML.format(scene=tiny_scene, out=run, cache=tmp_path / "cache"))
    code, out, err = run_cli("run", config)
    assert code == 0, err
    for stage in STAGES:
        assert f"  {stage:<17} ran   0  skipped   1  failed   0" in out, out


def test_imported_episodes_are_stamped_by_the_import(staged_run, run_cli, tmp_path):
    """import-sage-episodes replaces the scene's episodes: its stamp vouches for them from then on (gen-trajectories'
    no longer does), so verify passes, and a stray shard beside them is named as not the import's."""
    run = _copy(staged_run, tmp_path / "run")
    assert run_cli("export-sage", run, "--out", tmp_path / "sage")[0] == 0
    gvln = tmp_path / "sage" / "tiny" / "trajectories_tiny.json"
    assert run_cli("import-sage-episodes", gvln, "--run", run)[0] == 0
    assert not (run / ".stamps" / "tiny" / "gen_trajectories.json").exists()
    assert run_cli("verify", run)[0] == 0
    shutil.copy(_shard(run), run / "episodes" / "tiny" / "part-train-00009.parquet")
    line = refused(run_cli, ["validate", run, "--frames-per-scene", "0"], tmp_path, "part-train-00009.parquet")
    assert line == (f"error: {run / 'episodes' / 'tiny' / 'part-train-00009.parquet'}: not written by "
                    "import-sage-episodes: its stamp .stamps/tiny/import_sage.json does not list it; remove it, or "
                    "run import-sage-episodes again")
