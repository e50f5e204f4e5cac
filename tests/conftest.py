"""Fixtures shared across test files: the CLI runner and the demo scene."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest
from hypothesis import settings

import profiles  # noqa: F401 - registers the hypothesis profiles
from fake_llm import FakeLLM

from sagebench.cli import main
from sagebench.ui import SETTINGS

settings.load_profile("ci")  # `--hypothesis-profile=explore` (make explore) replaces it


@pytest.fixture
def run_cli(capsys) -> Callable[..., tuple[int, str, str]]:
    """Run `sagebench ARGS...` in-process; returns (exit code, stdout, stderr)."""

    def run(*args: str) -> tuple[int, str, str]:
        with pytest.raises(SystemExit) as exc:
            main([str(a) for a in args])
        SETTINGS.quiet = SETTINGS.debug = False
        out, err = capsys.readouterr()
        code = exc.value.code
        return (0 if code is None else int(code)), out, err

    return run


@pytest.fixture(scope="session")
def demo_scene_dir(tmp_path_factory) -> Path:
    """The default demo apartment (seed 0), written once per test session. Do not modify it."""
    from sagebench.scene.synth import write_synth_scene

    out = tmp_path_factory.mktemp("demo") / "demo_apartment_0"
    write_synth_scene(out, seed=0)
    return out


@pytest.fixture(scope="session")
def demo_built_run(demo_scene_dir, tmp_path_factory) -> Path:
    """A run directory holding build-scene's output for the demo apartment (scenes/demo_apartment_0/).

    Shared and read-only: copy `scenes/` into your own run directory before writing into one.
    """
    from sagebench.stages.build_scene import build_scene

    run = tmp_path_factory.mktemp("demo_run")
    build_scene(demo_scene_dir, run)
    return run


@pytest.fixture(scope="session")
def interiorgs_demo(demo_scene_dir, tmp_path_factory):
    """The demo apartment as an InteriorGS scene folder (tests/interiorgs_fixture.py), with what the folder does not
    say (each Gaussian's and label's instance, the mesh maps): (folder, Truth). Do not modify it."""
    from interiorgs_fixture import write_interiorgs_folder

    out = tmp_path_factory.mktemp("interiorgs") / "0001_839920"
    return out, write_interiorgs_folder(demo_scene_dir, out)


@pytest.fixture(scope="session")
def interiorgs_imported(interiorgs_demo, tmp_path_factory) -> Path:
    """`sagebench import-interiorgs` of the demo folder: the scene directory it wrote. Do not modify it."""
    from sagebench.stages.import_interiorgs import import_interiorgs_scene

    out = tmp_path_factory.mktemp("interiorgs_imported") / "scene"
    import_interiorgs_scene(interiorgs_demo[0], out)
    return out


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
def demo_eval_run(demo_built_run, tmp_path_factory) -> Path:
    """The demo apartment with 8 trajectories (their episode rows) and scene.xml, for evaluate and baseline tests.

    Shared and read-only: copy it before writing into it.
    """
    import shutil

    from sagebench.stages.export_usd import export_usd
    from sagebench.stages.gen_trajectories import GenTrajectoriesConfig, gen_trajectories

    run = tmp_path_factory.mktemp("eval_run")
    shutil.copytree(demo_built_run / "scenes", run / "scenes")
    gen_trajectories(run, GenTrajectoriesConfig(per_scene=8, seed=0))
    export_usd(run, cache_dir=tmp_path_factory.mktemp("eval_coacd_cache"))
    return run


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
