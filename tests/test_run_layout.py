"""The run layout's CONTRACT is complete and is what the stamps use.

Each stage, run in a fresh directory holding only the files the contract says it reads, writes the same
bytes as in a full run, and nothing but the files the contract says it writes; changing any file it
reads makes its stamp stale. So a stage that starts reading a file the contract does not list fails here.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from sagebench.pipeline.manifest import hash_run, sha256_file
from sagebench.pipeline.tasks import STAGES, Task, run_task, stage_key, stamp_path, up_to_date
from sagebench.errors import DataError
from sagebench.run_layout import (
    CONTRACT, MANIFEST, OUTPUT_ROOTS, STAMPS, after, files, producer, run_scenes, stage_files,
)

SCENE = "tiny"


def _settings() -> dict[str, dict]:
    from sagebench.settings.export_usd import ExportConfig
    from sagebench.settings.validate import ValidateConfig
    from sagebench.stages.gen_trajectories import GenTrajectoriesConfig
    from sagebench.topdown.builder import BuildSceneConfig

    return {"build_scene": BuildSceneConfig().model_dump(mode="json"),
            "gen_trajectories": GenTrajectoriesConfig(per_scene=6).model_dump(mode="json"),
            "export_usd": ExportConfig().model_dump(mode="json"),
            "validate": ValidateConfig(frames_per_scene=1).model_dump(mode="json")}


@pytest.fixture(scope="module")
def full_run(tiny_scene, tmp_path_factory) -> tuple[Path, Path]:
    """Every stage of the tiny scene (test_fuzz_inputs.py) run by the pipeline's run_task in order; (run dir, cache)."""
    run, cache = tmp_path_factory.mktemp("full_run"), tmp_path_factory.mktemp("layout_cache")
    settings = _settings()
    for name in STAGES:
        outcome = run_task(Task(name, SCENE, tiny_scene, run, settings[name], cache))
        assert outcome.status == "ran" and outcome.ok, outcome
    return run, cache


def _rel_hashes(paths: list[Path], root: Path) -> dict[str, str]:
    return {p.relative_to(root).as_posix(): sha256_file(p) for p in paths}


def test_every_file_of_a_run_is_written_by_exactly_one_stage(full_run):
    run, _ = full_run
    written = [p.relative_to(run).as_posix() for name in STAGES for p in stage_files(name, "writes", run, SCENE)]
    assert len(written) == len(set(written))
    assert sorted(written) == sorted(hash_run(run))  # the manifest's files: everything under OUTPUT_ROOTS
    assert set(OUTPUT_ROOTS) == {"scenes", "episodes", "previews", "validation", "reports"}


def test_stages_wait_for_the_stages_that_write_what_they_read():
    assert after("build_scene") == ()
    assert after("gen_trajectories") == ("build_scene",) and after("export_usd") == ("build_scene",)
    assert set(after("validate")) == {"build_scene", "gen_trajectories", "export_usd"}
    for name, contract in CONTRACT.items():
        assert all(p.root == "source" or producer(p) in STAGES for p in contract.reads), name


@pytest.mark.parametrize("stage", list(STAGES))
def test_a_stage_needs_only_the_files_it_declares(stage, full_run, tiny_scene, tmp_path):
    run, cache = full_run
    alone = tmp_path / "run"
    for p in stage_files(stage, "reads", run, SCENE, tiny_scene):
        if p.is_relative_to(run):
            (alone / p.relative_to(run)).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(p, alone / p.relative_to(run))
    before = {p for p in alone.rglob("*") if p.is_file()}

    outcome = run_task(Task(stage, SCENE, tiny_scene, alone, _settings()[stage], cache))

    assert outcome.status == "ran" and outcome.ok, outcome.message
    new = {p for p in alone.rglob("*") if p.is_file() and STAMPS not in p.relative_to(alone).parts} - before
    declared = stage_files(stage, "writes", alone, SCENE, tiny_scene)
    assert new <= set(declared) and declared  # nothing written beyond the contract
    assert _rel_hashes(declared, alone) == _rel_hashes(stage_files(stage, "writes", run, SCENE), run)


def _baseline(run: Path, out: Path) -> bytes:
    from sagebench.stages.rollout import BaselineConfig, run_baseline

    run_baseline(run, out / "oracle.jsonl", BaselineConfig(agent_name="oracle"))
    return (out / "oracle.jsonl").read_bytes()


def _evaluate(run: Path, out: Path) -> bytes:
    """Scores predictions without collision intensities, so the poses are replayed against the colliders."""
    from sagebench.stages.evaluate import evaluate

    lines = _baseline(run, out).decode().splitlines()
    bare = [json.dumps({k: v for k, v in json.loads(line).items() if k not in ("collision_intensity", "intensity_source")}) for line in lines]
    (out / "bare.jsonl").write_text("\n".join(bare) + "\n")
    result = evaluate(run, out / "bare.jsonl").to_json()
    assert result["intensity_replayed"] == len(lines) > 0
    return json.dumps(result["overall"]).encode()


def _render(run: Path, out: Path) -> bytes:
    from sagebench.settings.render import RenderConfig
    from sagebench.stages.render import render_view

    frame = render_view(run, SCENE, (1.0, 1.0, 0.5), RenderConfig(width=32, height=24))
    return frame.rgb.tobytes() + frame.depth.tobytes()


def _export_vlnce(run: Path, out: Path) -> bytes:
    from sagebench.stages.export_vlnce import export_vlnce

    # vlnce_opts.txt names `out` by its absolute path: the rest must match
    return b"".join(p.read_bytes() for p in export_vlnce(run, out).files if p.name != "vlnce_opts.txt")


def _rollout(run: Path, out: Path) -> bytes:
    from sagebench.stages.rollout import make_config, run_rollout

    run_rollout(run, out / "r.jsonl", make_config({"--width": 16, "--height": 12, "--episodes": 2, "--max-steps": 3}))
    return (out / "r.jsonl").read_bytes() + (out / "r_contact_sheet.png").read_bytes()


@pytest.mark.parametrize("command, call", [("baseline", _baseline), ("evaluate", _evaluate), ("render", _render),
                                           ("export_vlnce", _export_vlnce), ("rollout", _rollout)])
def test_commands_outside_the_pipeline_need_only_the_files_they_declare(command, call, full_run, tmp_path):
    run, _ = full_run
    alone = tmp_path / "run"
    for p in stage_files(command, "reads", run, SCENE):
        (alone / p.relative_to(run)).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(p, alone / p.relative_to(run))
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    assert call(alone, tmp_path / "a") == call(run, tmp_path / "b")


@pytest.mark.parametrize("stage", list(STAGES))
def test_changing_any_file_a_stage_reads_makes_it_rerun(stage, full_run, tiny_scene, tmp_path):
    run, cache = full_run
    source = tmp_path / "source"
    shutil.copytree(tiny_scene, source)
    task = Task(stage, SCENE, source, run, _settings()[stage], cache)
    stamp = json.loads(stamp_path(task).read_text())
    assert up_to_date(task, stage_key(task, STAGES[stage].inputs(task)))  # nothing changed: skipped
    assert stamp["key"] == stage_key(task, STAGES[stage].inputs(task))
    checked = 0
    for place in CONTRACT[stage].reads:
        for path in files(place, run, SCENE, source)[:2]:  # the first two files of each declared place
            data = path.read_bytes()
            try:
                path.write_bytes(data + b"\n")
                assert not up_to_date(task, stage_key(task, STAGES[stage].inputs(task))), path
            finally:
                path.write_bytes(data)
            checked += 1
    assert checked >= len(CONTRACT[stage].reads)
    assert up_to_date(task, stage_key(task, STAGES[stage].inputs(task)))


def test_the_readme_output_layout_names_every_file_the_stages_write():
    readme = (Path(__file__).resolve().parents[1] / "README.md").read_text()
    block = readme.split("## Output layout", 1)[1].split("```", 2)[1]
    roots = {"scene": "scenes/<scene_id>/", "episodes": "episodes/<scene_id>/", "validation": "validation/<scene_id>/",
             "previews": "previews/<scene_id>/", "reports": "reports/<scene_id>/"}
    for name, contract in CONTRACT.items():
        for place in contract.writes:
            assert roots[place.root] in block, (name, place)
            if place.meshes:
                assert "meshes/" in block
            elif place.rel != ".":
                assert place.rel in block, (name, place)
    assert MANIFEST in block


def test_mesh_names_stay_inside_the_scene_directory(tmp_path):
    from sagebench.run_layout import mesh_names

    spec = tmp_path / "scene.json"
    spec.write_text(json.dumps({"objects": [{"mesh": "meshes/a.glb"}, {"mesh": "../x.glb"}, {"mesh": "/etc/passwd"},
                                            {"mesh": "meshes/a.glb"}, {"mesh": 3}, "junk"]}))
    assert mesh_names(spec) == ["meshes/a.glb"]
    spec.write_text("[1]")
    assert mesh_names(spec) == [] and mesh_names(tmp_path / "absent.json") == []


def test_one_function_finds_a_runs_scenes_and_says_what_is_missing(tmp_path):
    """Built scenes have scenes/<id>/scene.json, scenes with episodes a shard; hidden, empty and half-made
    folders are no scenes. Every command asks run_scenes, so they all refuse a missing scene with this line."""
    for sid in ("b", "a", ".tmp-c"):
        (tmp_path / "scenes" / sid).mkdir(parents=True)
        (tmp_path / "scenes" / sid / "scene.json").write_text("{}")
    (tmp_path / "scenes" / "no_spec").mkdir()
    (tmp_path / "episodes" / "b").mkdir(parents=True)
    (tmp_path / "episodes" / "b" / "part-train-00000.parquet").write_bytes(b"")
    (tmp_path / "episodes" / "a" / "_preview").mkdir(parents=True)  # a preview but no shard
    assert run_scenes(tmp_path) == ["a", "b"]
    assert run_scenes(tmp_path, "b") == ["b"]
    assert run_scenes(tmp_path, having="episodes") == ["b"]
    with pytest.raises(DataError) as err:
        run_scenes(tmp_path, "no_spec")
    assert str(err.value) == (f"{tmp_path}: no scenes/no_spec/scene.json (scenes found: a, b); "
                              "run `sagebench build-scene` on this run first")
    with pytest.raises(DataError) as err:
        run_scenes(tmp_path, "a", having="episodes")
    assert str(err.value) == (f"{tmp_path}: no episodes/a/part-*.parquet (scenes found: b); "
                              "run `sagebench gen-trajectories` on this run first")
    with pytest.raises(DataError) as err:
        run_scenes(tmp_path / "empty", having="episodes")
    assert str(err.value) == (f"{tmp_path / 'empty'}: no episodes/<scene_id>/part-*.parquet (scenes found: none); "
                              "run `sagebench gen-trajectories` on this run first")
