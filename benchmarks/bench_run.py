"""Scenes per hour through `sagebench run` (all four stages) on demo apartments, 1 worker vs 2 processes."""

from __future__ import annotations

import tempfile
import time
from collections import defaultdict
from pathlib import Path

from sagebench.pipeline.config import load_run_config
from sagebench.pipeline.run import run_pipeline
from sagebench.scene.synth import write_synth_scene
from sagebench.ui import SETTINGS

SCENES = 4


def run() -> list[dict]:
    SETTINGS.quiet = True
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        for seed in range(SCENES):
            write_synth_scene(root / "scenes" / f"s{seed}", seed=seed)
        for workers in (1, 2):
            config_path = root / f"w{workers}.toml"
            config_path.write_text(f'scenes = ["scenes/*"]\nout = "w{workers}"\ncache_dir = "cache"\n')
            summary = run_pipeline(load_run_config(config_path, workers=workers), config_path)
            per_stage: dict[str, float] = defaultdict(float)
            for o in summary.outcomes:
                per_stage[o.stage] += o.seconds
            start = time.perf_counter()
            rerun = run_pipeline(load_run_config(config_path, workers=workers), config_path)
            rows.append({
                "workers": workers, "scenes": SCENES, "episodes": summary.episodes,
                "wall s": summary.wall_seconds, "scenes/hour": SCENES / summary.wall_seconds * 3600,
                **{f"{k} s/scene": v / SCENES for k, v in per_stage.items()},
                "re-run (all skipped) s": time.perf_counter() - start,
                "all ok": summary.ok and rerun.ok,
            })
    return rows
