"""A run compiles its JIT kernels once, before its workers fan out, so no worker compiles one itself."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from sagebench.scene.synth import write_synth_scene


def _run(env: dict[str, str], code: str, cwd: Path) -> str:
    done = subprocess.run([sys.executable, "-c", code], env=env, cwd=cwd, capture_output=True, text=True, timeout=900)
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    return done.stdout + done.stderr


@pytest.mark.slow  # a cold numba cache compiles every kernel (about 20 CPU-s), then a demo run: CI runs it
def test_warmed_kernels_are_every_kernel_a_run_compiles(tmp_path):
    """With a cold numba cache, compile_kernels() writes every kernel the four stages then call: a run after it
    (its own process, as a worker is) compiles nothing and only loads from the cache."""
    write_synth_scene(tmp_path / "scenes" / "a", seed=0)
    (tmp_path / "r.toml").write_text('scenes = ["scenes/*"]\nout = "r"\n[gen_trajectories]\nper_scene = 10\n'
                                     '[validate]\nframes_per_scene = 1\n')
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "numba"), "NUMBA_DEBUG_CACHE": "1"}
    warm = _run(env, "from sagebench.pipeline.kernels import compile_kernels; compile_kernels()", tmp_path)
    assert "data saved" in warm
    ran = _run(env, "from sagebench.cli import main; main(['-q', 'run', 'r.toml'])", tmp_path)
    assert "data loaded" in ran
    assert [line for line in ran.splitlines() if "data saved" in line] == []


@pytest.mark.parametrize("workers", [1, 2])
def test_kernels_are_compiled_before_the_first_task_only_with_workers(tmp_path, monkeypatch, workers):
    from sagebench.pipeline import run as run_mod
    from sagebench.pipeline.config import load_run_config

    events: list[str] = []

    class Scheduler:
        def __init__(self, executor, *args):
            self.pieces = []

        def outcomes(self):
            events.append("first task")
            return iter(())

    monkeypatch.setattr(run_mod, "compile_kernels", lambda: events.append("compile"))
    monkeypatch.setattr(run_mod, "RunScheduler", Scheduler)
    write_synth_scene(tmp_path / "scenes" / "a", seed=0)
    config = tmp_path / "r.toml"
    config.write_text('scenes = ["scenes/*"]\nout = "r"\n')
    run_mod.run_pipeline(load_run_config(config, workers=workers), config)
    assert events == (["compile", "first task"] if workers > 1 else ["first task"])
