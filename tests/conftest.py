"""Fixtures shared across test files: the CLI runner and the demo scene."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest

from sagebench.cli import main
from sagebench.ui import SETTINGS


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
