"""What a user waits for at the command line: each command run as a subprocess, against the same work in-process.

Start-up (`--help`, a bad scene refused in one line; target 0.5 s, with a bare `python -c pass` as the floor),
gen-trajectories --per-scene 200, the validate stage, `run` on two demo apartments and a no-op re-run; then each
command's CPU-seconds beside the same command run on REFERENCE's code (git archive, same environment: what the lazy
imports and the passive wait by default of issue 40 saved, alternated runs). Every
command runs once untimed first (numba's cache and the OS file cache warm, as for a user's second call);
figures are the median of several runs where a run is short. The load average is in the notes: other work
on the machine slows subprocess start-up most.
"""

from __future__ import annotations

import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from benchmarks.demo_run import built_demo_run

TARGET_S = 0.5
SCENE = "demo_apartment_0"
REFERENCE = "fea28b8"  # main before issue 40's start-up work


def _cli() -> list[str]:
    script = Path(sys.executable).parent / "sagebench"
    return [str(script)] if script.is_file() else [sys.executable, "-m", "sagebench"]


def _time(cmd: list[str], *, repeat: int = 1, ok: tuple[int, ...] = (0,)) -> tuple[float, str]:
    """Median wall seconds of `repeat` runs after one warm-up run; checks the exit status; last stderr."""
    times, err = [], ""
    for i in range(repeat + 1):
        start = time.perf_counter()
        proc = subprocess.run(cmd, capture_output=True, text=True)
        if i:
            times.append(time.perf_counter() - start)
        if proc.returncode not in ok:
            raise RuntimeError(f"{' '.join(cmd)}: exit {proc.returncode}: {proc.stderr.strip()[-500:]}")
        err = proc.stderr
    return statistics.median(times), err


def _load() -> str:
    return "load avg %.2f %.2f %.2f" % os.getloadavg()


def run() -> list[dict]:
    from sagebench.pipeline.config import load_run_config
    from sagebench.pipeline.run import run_pipeline
    from sagebench.scene.synth import write_synth_scene
    from sagebench.settings.validate import ValidateConfig
    from sagebench.stages.gen_trajectories import GenTrajectoriesConfig, generate_scene
    from sagebench.stages.validate import validate_scene
    from sagebench.ui import SETTINGS

    SETTINGS.quiet = True
    cli = _cli()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        floor, _ = _time([sys.executable, "-c", "pass"], repeat=5)
        help_s, _ = _time([*cli, "--help"], repeat=5)
        rows.append({"name": "sagebench --help", "reference": f"target {TARGET_S} s", "cli s": help_s,
                     "in-process s": "", "ratio": help_s / TARGET_S,
                     "notes": f"bare `python -c pass` {floor:.3f} s; {_load()}"})
        bad = root / "bad_scene"
        bad.mkdir()
        (bad / "scene.json").write_text('{"scene_id": 3}')
        refuse_s, err = _time([*cli, "build-scene", str(bad), "--out", str(root / "bad_run")], repeat=5, ok=(2,))
        assert len(err.strip().splitlines()) == 1 and not (root / "bad_run").exists(), err
        rows.append({"name": "build-scene refusing a bad scene.json (exit 2)", "reference": f"target {TARGET_S} s",
                     "cli s": refuse_s, "in-process s": "", "ratio": refuse_s / TARGET_S,
                     "notes": err.strip()[:70]})

        run_dir = built_demo_run(root / "demo")
        scene_dir = run_dir / "scenes" / SCENE
        config = GenTrajectoriesConfig(per_scene=200)
        generate_scene(scene_dir, root / "warm", config)
        in_s = statistics.median(_timed(lambda: generate_scene(scene_dir, root / "gen", config)) for _ in range(3))
        pairs = generate_scene(scene_dir, root / "gen", config).rows
        cli_s, _ = _time([*cli, "gen-trajectories", str(run_dir), "--per-scene", "200"], repeat=3)
        rows.append({"name": "gen-trajectories --per-scene 200, pairs/s", "reference": "in-process generate_scene",
                     "cli s": cli_s, "in-process s": in_s, "ratio": cli_s / in_s,
                     "notes": f"{pairs} pairs: {pairs / cli_s:.0f}/s from the CLI, {pairs / in_s:.0f}/s in-process"})

        vconfig = ValidateConfig()
        trajectories = validate_scene(run_dir, SCENE, vconfig).trajectories
        in_s = statistics.median(_timed(lambda: validate_scene(run_dir, SCENE, vconfig)) for _ in range(3))
        cli_s, _ = _time([*cli, "validate", str(run_dir)], repeat=3)
        rows.append({"name": "validate stage, trajectories/s", "reference": "in-process validate_scene",
                     "cli s": cli_s, "in-process s": in_s, "ratio": cli_s / in_s,
                     "notes": f"{trajectories} trajectories: {trajectories / cli_s:.0f}/s from the CLI, "
                              f"{trajectories / in_s:.0f}/s in-process"})

        for seed in range(2):
            write_synth_scene(root / "scenes" / f"s{seed}", seed=seed)
        toml = 'scenes = ["scenes/*"]\nout = "{out}"\ncache_dir = "cache"\n'
        for out in ("warm", "cli", "inproc"):
            (root / f"{out}.toml").write_text(toml.format(out=out))
        subprocess.run([*cli, "-q", "run", str(root / "warm.toml")], check=True, capture_output=True)  # caches warm
        start = time.perf_counter()
        subprocess.run([*cli, "-q", "run", str(root / "cli.toml")], check=True, capture_output=True)
        cli_s = time.perf_counter() - start
        in_s = _timed(lambda: run_pipeline(load_run_config(root / "inproc.toml"), root / "inproc.toml"))
        rows.append({"name": "run, 2 demo apartments, 1 worker, scenes/h", "reference": "in-process run_pipeline",
                     "cli s": cli_s, "in-process s": in_s, "ratio": cli_s / in_s,
                     "notes": f"{2 / cli_s * 3600:.0f} scenes/h from the CLI, {2 / in_s * 3600:.0f} in-process"})
        cli_s, _ = _time([*cli, "-q", "run", str(root / "cli.toml")], repeat=3)
        in_s = statistics.median(
            _timed(lambda: run_pipeline(load_run_config(root / "inproc.toml"), root / "inproc.toml"))
            for _ in range(3))
        rows.append({"name": "run re-run, everything skipped", "reference": "in-process run_pipeline",
                     "cli s": cli_s, "in-process s": in_s, "ratio": cli_s / in_s, "notes": _load()})
        rows += _against_reference(root, cli, root / "cli", SCENE)
    return rows


def _cpu(cmd: list[str], env: dict[str, str], cwd: Path, ok: tuple[int, ...] = (0, 1)) -> float:
    """CPU-seconds (user + system) of one run of `cmd` and its children."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    proc = subprocess.run(cmd, capture_output=True, text=True, env=env, cwd=cwd)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode not in ok:
        raise RuntimeError(f"{' '.join(cmd)}: exit {proc.returncode}: {proc.stderr.strip()[-500:]}")
    return after.ru_utime - before.ru_utime + after.ru_stime - before.ru_stime


def _against_reference(root: Path, cli: list[str], run_dir: Path, scene: str, repeat: int = 3) -> list[dict]:
    """Each command's median CPU-s here and on REFERENCE's sagebench, runs alternated after one warm-up each; the
    environment without thread settings of its own (what a user's shell has)."""
    ref = root / "reference"
    ref.mkdir()
    archive = subprocess.run(["git", "archive", REFERENCE, "sagebench"], capture_output=True, check=True,
                             cwd=Path(__file__).parent.parent).stdout
    subprocess.run(["tar", "-x", "-C", str(ref)], input=archive, check=True)
    env = {k: v for k, v in os.environ.items() if k not in ("OMP_WAIT_POLICY", "NUMBA_NUM_THREADS", "PYTHONPATH")}
    envs = {"here": env, "ref": env | {"PYTHONPATH": str(ref)}}  # before the editable install's finder
    py = [sys.executable, "-m", "sagebench", "-q"]
    preds = root / "oracle.jsonl"
    subprocess.run([*cli, "-q", "baseline", "--agent", "oracle", "--run", str(run_dir), "--out", str(preds)],
                   check=True, capture_output=True)
    commands = {"--help": ["--help"], "verify": ["verify", str(run_dir)],
                "evaluate (oracle)": ["evaluate", "--run", str(run_dir), "--predictions", str(preds)],
                "validate --scene": ["validate", str(run_dir), "--scene", scene],
                "gen-trajectories --per-scene 8": ["gen-trajectories", str(run_dir), "--scene", scene, "--per-scene", "8"]}
    rows = []
    for name, args in commands.items():
        cpu: dict[str, list[float]] = {"here": [], "ref": []}
        for i in range(repeat + 1):
            for who in ("here", "ref"):
                t = _cpu([*py, *args], envs[who], root)  # not the checkout: `-m` puts the cwd first
                if i:
                    cpu[who].append(t)
        here, before = statistics.median(cpu["here"]), statistics.median(cpu["ref"])
        rows.append({"name": f"{name}: CPU-s", "reference": f"{REFERENCE} (main before)", "cli s": here,
                     "in-process s": before, "ratio": before / here,
                     "notes": f"CPU-s here {here:.2f}, on {REFERENCE} {before:.2f}; {_load()}"})
    return rows


def _timed(fn) -> float:
    start = time.perf_counter()
    fn()
    return time.perf_counter() - start


if __name__ == "__main__":
    for row in run():
        print(row)
