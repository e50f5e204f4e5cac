"""ImageNav's goal image: a PNG file the episode names (imported episodes) is what the agent is shown; a rendered
goal (`render:x,y,yaw`) is rendered; a named file that is missing, not a PNG or not the rgb observation's size is
refused in one line before the rollout writes anything."""

from __future__ import annotations

import shutil
from pathlib import Path

import cv2
import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from test_fuzz_inputs import snapshot

SIZE = (64, 48)  # the rgb observation, px (width, height)
GREEN = (10, 200, 30)


@pytest.fixture(scope="module")
def imagenav_run(tiny_goal_tasks_run, tmp_path_factory) -> Path:
    """tiny_goal_tasks_run, whose first imagenav episode names goals/first.png (a flat green image); the second keeps
    its rendered goal. Read-only: copy it."""
    run = tmp_path_factory.mktemp("imagenav") / "run"
    shutil.copytree(tiny_goal_tasks_run, run)
    (shard,) = (run / "episodes" / "tiny").glob("part-*.parquet")  # the tiny run has one split
    table = pq.read_table(shard)
    first = table.column("task").to_pylist().index("imagenav")
    images = table.column("goal_image").to_pylist()
    images[first] = "goals/first.png"
    i = table.schema.get_field_index("goal_image")
    pq.write_table(table.set_column(i, table.schema.field(i), pa.array(images, pa.string())), shard)
    (run / "goals").mkdir()
    cv2.imwrite(str(run / "goals" / "first.png"), np.full((SIZE[1], SIZE[0], 3), GREEN[::-1], np.uint8))
    return run


def _imagenav_ids(run: Path) -> list[str]:
    from sagebench.episodes.load import load_episodes

    return [e.episode_id for e in load_episodes(run) if e.task == "imagenav"]


def test_a_goal_image_file_is_what_the_agent_sees_and_a_recipe_is_rendered(imagenav_run):
    from sagebench.navsim.simulator import Simulator
    from sagebench.settings.rollout import EnvConfig

    sim = Simulator(imagenav_run, EnvConfig(task="imagenav", observations=("rgb",), width=SIZE[0], height=SIZE[1]))
    named, rendered = (r.observation["imagegoal"] for r in sim.start(_imagenav_ids(imagenav_run)))
    assert named.shape == rendered.shape == (SIZE[1], SIZE[0], 3)
    assert (named == np.array(GREEN, np.uint8)).all()
    assert not (rendered == np.array(GREEN, np.uint8)).all()  # rendered from its goal pose, not the file


@pytest.mark.parametrize("damage, expect", [
    (lambda p: p.unlink(), "cannot read: No such file or directory"),
    (lambda p: p.write_bytes(b"GIF89a not a png"), "is not a PNG file"),
    (lambda p: cv2.imwrite(str(p), np.zeros((10, 20, 3), np.uint8)), "is 20x10 px; the rgb observation is 64x48"),
], ids=["missing", "not-png", "wrong-size"])
def test_a_bad_goal_image_file_is_refused_with_nothing_written(damage, expect, imagenav_run, run_cli, tmp_path):
    run = tmp_path / "run"
    shutil.copytree(imagenav_run, run)
    damage(run / "goals" / "first.png")
    before = snapshot(tmp_path)
    code, out, err = run_cli("rollout", "--run", run, "--policy", "stationary", "--task", "imagenav", "--obs", "rgb",
                             "--width", SIZE[0], "--height", SIZE[1], "--out", tmp_path / "p.jsonl")
    first = _imagenav_ids(run)[0]
    assert (code, err) == (2, f"error: {run / 'goals' / 'first.png'}: goal_image of episode {first}: {expect}\n")
    assert snapshot(tmp_path) == before
