"""A stage's stamp: an unchanged stage is skipped, a changed setting or library version makes it run again."""

from __future__ import annotations

import json
import shutil

from sagebench.episodes.shards import read_episodes
from sagebench.settings.shared import AgentConfig

from sagebench import stamps
from sagebench.pipeline import tasks
from sagebench.pipeline.tasks import Task, run_task, stamp_path
from sagebench.stages.gen_trajectories import GenTrajectoriesConfig
from sagebench.versions import output_versions

SCENE = "demo_apartment_0"


def test_a_changed_setting_reruns_a_stamped_stage(demo_built_run, demo_scene_dir, tmp_path):
    run = tmp_path / "run"
    shutil.copytree(demo_built_run / "scenes", run / "scenes")

    def gen(per_scene: int) -> str:
        settings = GenTrajectoriesConfig(per_scene=per_scene, seed=0).model_dump(mode="json")
        return run_task(Task("gen_trajectories", SCENE, demo_scene_dir, run, settings)).status

    assert gen(3) == "ran"
    key = json.loads(stamp_path(Task("gen_trajectories", SCENE, demo_scene_dir, run, {})).read_text())["key"]
    assert gen(3) == "skipped"
    assert gen(4) == "ran"  # the stamp of per_scene=3 is stale
    stamp = json.loads(stamp_path(Task("gen_trajectories", SCENE, demo_scene_dir, run, {})).read_text())
    assert stamp["key"] != key
    shard = read_episodes(run / "episodes" / SCENE)
    assert len(set(shard.column("trajectory_id").to_pylist())) == 4
    assert gen(4) == "skipped"


def test_a_stamp_records_the_agent_its_stage_worked_for_and_another_body_reruns_it(demo_built_run, demo_scene_dir,
                                                                                   tmp_path):
    """The body comes from the scene's map (build-scene wrote it from the run's settings): a map built for
    another agent makes every stage that reads it run again, and its stamp says which agent."""
    run = tmp_path / "run"
    shutil.copytree(demo_built_run / "scenes", run / "scenes")
    settings = GenTrajectoriesConfig(per_scene=2, seed=0).model_dump(mode="json")
    task = Task("gen_trajectories", SCENE, demo_scene_dir, run, settings)
    assert run_task(task).status == "ran"
    assert json.loads(stamp_path(task).read_text())["agent"] == AgentConfig().model_dump(mode="json")
    smap = run / "scenes" / SCENE / "semantic_map.json"
    smap.write_text(smap.read_text().replace('"agent_radius": 0.2,', '"agent_radius": 0.25,'))
    assert run_task(task).status == "ran"
    assert json.loads(stamp_path(task).read_text())["agent"] == AgentConfig(radius=0.25).model_dump(mode="json")


def test_a_changed_library_version_reruns_a_stamped_stage(demo_built_run, demo_scene_dir, tmp_path, monkeypatch):
    run = tmp_path / "run"
    shutil.copytree(demo_built_run / "scenes", run / "scenes")
    settings = GenTrajectoriesConfig(per_scene=2, seed=0).model_dump(mode="json")
    task = Task("gen_trajectories", SCENE, demo_scene_dir, run, settings)
    assert run_task(task).status == "ran" and run_task(task).status == "skipped"
    older = output_versions() | {"pyarrow": "0.0.1"}  # Parquet bytes embed the writer's version
    monkeypatch.setattr(stamps, "output_versions", lambda: older)
    assert run_task(task).status == "ran"
    assert run_task(task).status == "skipped"


def test_a_tasks_warnings_come_back_in_its_outcome_not_on_stderr(demo_scene_dir, tmp_path, monkeypatch, capsys):
    """A Ray worker's stderr goes nowhere: run_task returns the warnings so the driver prints them."""
    from sagebench import ui

    def warns(t):
        ui.warn("only 3 of 5 trajectories")
        return "done", True

    monkeypatch.setitem(tasks.STAGES, "build_scene", tasks.Stage("build_scene", warns))
    outcome = run_task(Task("build_scene", SCENE, demo_scene_dir, tmp_path / "run", {}))
    assert outcome.status == "ran" and outcome.warnings == ("only 3 of 5 trajectories",)
    assert capsys.readouterr().err == ""
    ui.warn("after")  # printing again once the task is over
    assert capsys.readouterr().err == "warning: after\n"


def test_stages_ask_for_the_cpus_their_workers_use(demo_scene_dir, tmp_path):
    task = Task("export_usd", SCENE, demo_scene_dir, tmp_path, {"workers": 3})
    assert tasks.STAGES["export_usd"].cpus(task) == 3
    assert tasks.STAGES["build_scene"].cpus(Task("build_scene", SCENE, demo_scene_dir, tmp_path, {})) == 1
