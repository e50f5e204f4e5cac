"""`sagebench run` (all four stages) on demo apartments at 1, 2 (and, with more cores, 4, 8, ...) workers: wall
time and CPU-s per scene, this process and its workers together, with the load average at start and end.

The reference is the 1-worker row of the same run: workers that share the cores should cost about the same
CPU-s per scene. The JIT kernels are compiled before the first row, so no row pays for a cold cache.
"""

from __future__ import annotations

import os
import resource
import tempfile
import time
from pathlib import Path

from sagebench.pipeline.config import load_run_config
from sagebench.pipeline.kernels import compile_kernels
from sagebench.pipeline.run import run_pipeline
from sagebench.scene.synth import write_synth_scene
from sagebench.threads import available_cores
from sagebench.ui import SETTINGS

SCENES = 4


def _cpu_seconds() -> float:
    """CPU-s of this process and of its children that have ended (run's workers end with the run)."""
    return sum(r.ru_utime + r.ru_stime for r in (resource.getrusage(resource.RUSAGE_SELF),
                                                  resource.getrusage(resource.RUSAGE_CHILDREN)))


def worker_counts(cores: int) -> list[int]:
    """1, 2, then doubling while there are cores for it."""
    counts = [1, 2]
    while counts[-1] * 2 <= cores:
        counts.append(counts[-1] * 2)
    return counts


def run() -> list[dict]:
    SETTINGS.quiet = True
    compile_kernels()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        for seed in range(SCENES):
            write_synth_scene(root / "scenes" / f"s{seed}", seed=seed)
        for workers in worker_counts(available_cores()):
            config_path = root / f"w{workers}.toml"
            config_path.write_text(f'scenes = ["scenes/*"]\nout = "w{workers}"\ncache_dir = "cache{workers}"\n')
            load = os.getloadavg()[0]
            cpu = _cpu_seconds()
            start = time.perf_counter()
            summary = run_pipeline(load_run_config(config_path, workers=workers), config_path)
            wall, cpu = time.perf_counter() - start, _cpu_seconds() - cpu
            start = time.perf_counter()
            rerun = run_pipeline(load_run_config(config_path, workers=workers), config_path)
            rows.append({
                "workers": workers, "scenes": SCENES, "episodes": summary.episodes, "wall s": wall,
                "CPU-s/scene": cpu / SCENES, "cores busy": cpu / wall, "scenes/hour": SCENES / wall * 3600,
                "re-run (all skipped) s": time.perf_counter() - start, "load start": load,
                "load end": os.getloadavg()[0], "all ok": summary.ok and rerun.ok,
            })
    base = rows[0]["CPU-s/scene"]
    for row in rows:
        row["CPU-s vs 1 worker"] = row["CPU-s/scene"] / base
    return rows
