"""`sagebench build-scene`: outputs, options, and bad input."""

from __future__ import annotations

import json

import numpy as np



def test_builds_the_demo_scene(run_cli, demo_scene_dir, tmp_path):
    code, out, err = run_cli("-q", "build-scene", demo_scene_dir, "--out", tmp_path / "run", "--agent-radius", "0.25")
    assert code == 0, err
    assert out.startswith("build-scene demo_apartment_0: map ")
    assert "5/5 rooms reachable (navigable floor outside the main region: " in out
    scene = tmp_path / "run" / "scenes" / "demo_apartment_0"
    assert {"meshes", "scene.json", "semantic_map.json", "topdown.npz", "topdown.png"} <= {p.name for p in scene.iterdir()}
    assert json.loads((scene / "semantic_map.json").read_text())["agent_radius"] == 0.25


def test_options_map_onto_the_config(run_cli, tiny_scene, tmp_path):
    code, _, err = run_cli("build-scene", tiny_scene, "--out", tmp_path, "--resolution", "0.1", "--band-max", "0.5")
    assert code == 0, err
    with np.load(tmp_path / "scenes" / "tiny" / "topdown.npz") as z:
        assert float(z["resolution"]) == 0.1
    band = json.loads((tmp_path / "scenes" / "tiny" / "semantic_map.json").read_text())["band_m"]
    assert band == [0.05, 0.5]


def test_bad_scene_dir_exits_2_and_writes_nothing(run_cli, tmp_path):
    (tmp_path / "empty").mkdir()
    code, out, err = run_cli("build-scene", tmp_path / "empty", "--out", tmp_path / "run")
    assert code == 2 and out == ""
    assert err == f"error: {tmp_path / 'empty'}: no scene.json in this directory\n"
    assert not (tmp_path / "run").exists()


def test_bad_option_exits_2_and_writes_nothing(run_cli, demo_scene_dir, tmp_path):
    code, _, err = run_cli("build-scene", demo_scene_dir, "--out", tmp_path / "run", "--band-max", "0.01")
    assert code == 2
    assert err == "error: --band-max: 0.01 must be above the band's bottom, clearance (0.05)\n"
    assert not (tmp_path / "run").exists()


def test_help_says_what_it_reads_and_writes(run_cli):
    code, out, _ = run_cli("build-scene", "--help")
    assert code == 0
    text = " ".join(out.split())
    assert "Reads SCENE_DIR/scene.json" in text and "topdown.npz" in text and "semantic_map.json" in text


def test_prune_option_is_checked_before_anything_is_written(run_cli, demo_scene_dir, tmp_path):
    code, _, err = run_cli("build-scene", demo_scene_dir, "--out", tmp_path / "run", "--prune", "1.5")
    assert code == 2
    assert err == "error: --prune: Input should be less than 1\n"
    assert not (tmp_path / "run").exists()
