"""`sagebench demo`: the built-in scene through the whole pipeline (`sagebench run`), into one run directory."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from sagebench.fileio import write_text
from sagebench.pipeline.config import load_run_config
from sagebench.pipeline.run import RunSummary, run_pipeline
from sagebench.run_folder import check_scene_out, claim_run_dir
from sagebench.run_layout import BASELINES, DEMO_CONFIG, DEMO_CONFIG_HEADER, DEMO_INPUT
from sagebench.scene.loader import load_scene
from sagebench.scene.summary import summarise
from sagebench.scene.synth import is_synth_scene, write_synth_scene
from sagebench.ui import info

RUN_CONFIG = DEMO_CONFIG_HEADER + """ (`make demo` writes it).
scenes = ["input/demo_apartment_{seed}"]
out = "."
seed = {seed}

[gen_trajectories.splits]  # one scene: none to hold out for the unseen splits, so train and val_seen only
val_unseen = 0.0
test = 0.0
"""


@dataclass(frozen=True)
class DemoResult:
    run: RunSummary
    scores: str  # the oracle baseline's evaluation table, empty when the run failed


def run_demo(out: Path, *, seed: int = 0, force: bool = False) -> DemoResult:
    """Write the demo scene and its run config into `out`, run every stage on it, then drive the oracle
    baseline through every episode and score it (out/baselines/). `out` must be new, empty or an earlier
    demo's, unless `force` (run_folder.claim_run_dir)."""
    with claim_run_dir(Path(out), "demo", force=force):
        return _demo(Path(out), seed)


def _demo(out: Path, seed: int) -> DemoResult:
    scene_dir = out / DEMO_INPUT / f"demo_apartment_{seed}"
    check_scene_out(scene_dir, "synth-scene", ours=is_synth_scene)
    write_synth_scene(scene_dir, seed=seed)
    info(f"demo scene: {scene_dir}")
    info(summarise(load_scene(scene_dir)))
    config_path = out / DEMO_CONFIG
    write_text(config_path, RUN_CONFIG.format(seed=seed))
    summary = run_pipeline(load_run_config(config_path), config_path)
    if not summary.ok:
        return DemoResult(summary, "")
    from sagebench.stages.evaluate import evaluate
    from sagebench.stages.rollout import BaselineConfig, run_baseline

    predictions = out / BASELINES / "oracle.jsonl"
    info(run_baseline(out, predictions, BaselineConfig(agent_name="oracle", seed=seed)).summary())
    scored = evaluate(out, predictions, out=out / BASELINES / "oracle_results.json")
    return DemoResult(summary, scored.table())
