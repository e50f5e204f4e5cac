"""Fixtures shared across test files: the CLI runner, the demo scene and its runs, the tiny scene and its runs."""

from __future__ import annotations

import functools
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import click
import pytest
import typer.main
from hypothesis import settings

import profiles  # noqa: F401 - registers the hypothesis profiles
from fake_llm import FakeLLM
from shared_fixtures import built_once

from sagebench.cli import main
from sagebench.ui import SETTINGS

settings.load_profile("ci")  # `--hypothesis-profile=explore` (make explore) replaces it


_build_click_command = typer.main.get_command


@functools.cache
def _click_command(app: typer.Typer) -> click.Command:
    """The click command typer builds from the app: typer builds it anew on every call of the app (50 ms, most of
    a refused input's test), a real `sagebench` process once; in-process runs build it once per test process."""
    return _build_click_command(app)


@pytest.fixture
def run_cli(capsys, monkeypatch) -> Callable[..., tuple[int, str, str]]:
    """Run `sagebench ARGS...` in-process; returns (exit code, stdout, stderr)."""
    monkeypatch.setattr(typer.main, "get_command", _click_command)

    def run(*args: str) -> tuple[int, str, str]:
        with pytest.raises(SystemExit) as exc:
            main([str(a) for a in args])
        SETTINGS.quiet = SETTINGS.debug = False
        out, err = capsys.readouterr()
        code = exc.value.code
        return (0 if code is None else int(code)), out, err

    return run


@pytest.fixture(scope="session")
def demo_scene_dir(tmp_path_factory) -> Iterator[Path]:
    """The default demo apartment (seed 0), written once per test run (shared_fixtures.py). Do not modify it."""
    from sagebench.scene.synth import write_synth_scene

    def build(folder: Path) -> Path:
        write_synth_scene(folder / "demo_apartment_0", seed=0)
        return folder / "demo_apartment_0"

    with built_once(tmp_path_factory, "demo_scene", build) as scene:
        yield scene


@pytest.fixture(scope="session")
def demo_built_run(demo_scene_dir, tmp_path_factory) -> Iterator[Path]:
    """A run directory holding build-scene's output for the demo apartment (scenes/demo_apartment_0/).

    Shared and read-only: copy `scenes/` into your own run directory before writing into one.
    """
    from sagebench.stages.build_scene import build_scene

    def build(folder: Path) -> Path:
        build_scene(demo_scene_dir, folder / "run")
        return folder / "run"

    with built_once(tmp_path_factory, "demo_run", build) as run:
        yield run


@pytest.fixture(scope="session")
def interiorgs_demo(demo_scene_dir, tmp_path_factory) -> Iterator[tuple[Path, Any]]:
    """The demo apartment as an InteriorGS scene folder (tests/interiorgs_fixture.py), with what the folder does not
    say (each Gaussian's and label's instance, the mesh maps): (folder, Truth). Do not modify it."""
    from interiorgs_fixture import write_interiorgs_folder

    def build(folder: Path) -> tuple[Path, Any]:
        out = folder / "0001_839920"
        return out, write_interiorgs_folder(demo_scene_dir, out)

    with built_once(tmp_path_factory, "interiorgs", build) as found:
        yield found


@pytest.fixture(scope="session")
def interiorgs_imported(interiorgs_demo, tmp_path_factory) -> Iterator[Path]:
    """`sagebench import-interiorgs` of the demo folder: the scene directory it wrote. Do not modify it."""
    from sagebench.stages.import_interiorgs import import_interiorgs_scene

    def build(folder: Path) -> Path:
        import_interiorgs_scene(interiorgs_demo[0], folder / "scene")
        return folder / "scene"

    with built_once(tmp_path_factory, "interiorgs_imported", build) as scene:
        yield scene


@pytest.fixture(scope="session")
def room_mjcf() -> str:
    """MJCF of a 6 x 6 m test room for the replay tests: a wall slab at x = 3 (x 2.95..3.05, 2.5 m tall),
    a table x 1.1..1.9, y 0.1..0.9 (0.75 m), a floor slab body `floor_3` and the ground plane, all mesh
    geoms in bodies named like export-usd's (`<category>_<instance_id>`)."""

    def box(name: str, lo: tuple[float, float, float], hi: tuple[float, float, float]) -> str:
        v = [(x, y, z) for z in (lo[2], hi[2]) for y in (lo[1], hi[1]) for x in (lo[0], hi[0])]
        return f"<mesh name='{name}' vertex='{' '.join(f'{a} {b} {c}' for a, b, c in v)}'/>"

    return f"""<mujoco model='room'>
  <asset>{box('wall', (2.95, -3, 0), (3.05, 3, 2.5))}{box('table', (1.1, 0.1, 0), (1.9, 0.9, 0.75))}
         {box('slab', (-3, -3, -0.1), (3, 3, 0.0))}</asset>
  <worldbody>
    <geom name='ground' type='plane' size='0 0 1'/>
    <body name='wall_1'><geom name='wall_1_p000' type='mesh' mesh='wall'/></body>
    <body name='table_2'><geom name='table_2_p000' type='mesh' mesh='table'/></body>
    <body name='floor_3'><geom name='floor_3_p000' type='mesh' mesh='slab'/></body>
  </worldbody>
</mujoco>"""


@pytest.fixture(scope="session")
def demo_eval_run(demo_built_run, tmp_path_factory) -> Iterator[Path]:
    """The demo apartment with 8 trajectories (their episode rows) and scene.xml, for evaluate and baseline tests.

    Shared and read-only: copy it before writing into it.
    """
    import shutil

    from sagebench.stages.export_usd import export_usd
    from sagebench.stages.gen_trajectories import GenTrajectoriesConfig, gen_trajectories

    def build(folder: Path) -> Path:
        run = folder / "run"
        shutil.copytree(demo_built_run / "scenes", run / "scenes")
        gen_trajectories(run, GenTrajectoriesConfig(per_scene=8, seed=0))
        export_usd(run, cache_dir=folder / "coacd_cache")
        return run

    with built_once(tmp_path_factory, "eval_run", build) as run:
        yield run


@pytest.fixture(scope="session")
def tiny_scene(tmp_path_factory) -> Iterator[Path]:
    """The tiny valid scene of tests/test_fuzz_inputs.py (one room, 5 objects). Do not modify it."""
    from test_fuzz_inputs import write_scene

    with built_once(tmp_path_factory, "tiny_scene", lambda folder: write_scene(folder / "tiny")) as scene:
        yield scene


@pytest.fixture(scope="session")
def tiny_run(tiny_scene, tmp_path_factory) -> Iterator[Path]:
    """The tiny scene built (few Gaussians), 4 trajectories, exported, and the oracle's predictions. Read-only."""
    from sagebench.settings.baseline import BaselineConfig
    from sagebench.settings.build_scene import BuildSceneConfig, SplatConfig
    from sagebench.stages.build_scene import build_scene
    from sagebench.stages.export_usd import export_usd
    from sagebench.stages.gen_trajectories import GenTrajectoriesConfig, gen_trajectories
    from sagebench.stages.rollout import run_baseline

    def build(folder: Path) -> Path:
        run = folder / "run"
        build_scene(tiny_scene, run, BuildSceneConfig(splats=SplatConfig(object_density=20.0, structure_density=5.0)))
        gen_trajectories(run, GenTrajectoriesConfig(per_scene=4, seed=0, min_geodesic_m=1.0))
        export_usd(run, cache_dir=folder / "coacd_cache")
        run_baseline(run, run / "baselines" / "oracle.jsonl", BaselineConfig(agent_name="oracle"))
        return run

    with built_once(tmp_path_factory, "tiny_run", build) as run:
        yield run


@pytest.fixture(scope="session")
def tiny_goal_tasks_run(tiny_run, tmp_path_factory) -> Iterator[Path]:
    """tiny_run with 2 episodes each of pointnav, objectnav and imagenav (goal images rendered from their recipes)
    beside its VLN ones. Read-only: copy it."""
    import shutil

    def build(folder: Path) -> Path:
        run = folder / "run"
        shutil.copytree(tiny_run, run)
        with pytest.raises(SystemExit) as done:
            main(["-q", "gen-trajectories", str(run), "--per-scene", "4", "--min-geodesic", "1", "--tasks",
                  "vln,pointnav,objectnav,imagenav", "--task-episodes", "2"])
        assert done.value.code in (0, None)
        return run

    with built_once(tmp_path_factory, "tiny_goal_tasks_run", build) as run:
        yield run


@pytest.fixture(scope="session")
def made_run(tiny_scene, tmp_path_factory) -> Iterator[Path]:
    """The tiny scene through `sagebench run` (a manifest, several shards). Read-only: copy it."""
    from test_fuzz_safety import TOML

    def build(folder: Path) -> Path:
        config = folder / "t.toml"
        config.write_text(TOML.format(scene=tiny_scene, out=folder / "out").replace("per_scene = 2", "per_scene = 8"))
        with pytest.raises(SystemExit) as done:
            main(["-q", "run", str(config)])
        assert done.value.code in (0, None)
        assert len(list((folder / "out" / "episodes" / "tiny").glob("part-*.parquet"))) >= 2
        return folder / "out"

    with built_once(tmp_path_factory, "made_run", build) as run:
        yield run


@pytest.fixture
def fake_llm():
    """Start fake OpenAI-compatible servers on 127.0.0.1 (start(respond, props=None) -> server; `props` is what GET
    /props answers, as a llama.cpp server reports its slots); all closed after the test."""
    servers: list[FakeLLM] = []

    def start(respond, props=None):
        servers.append(FakeLLM(respond, props))
        return servers[-1]

    yield start
    for s in servers:
        s.close()
