"""Evaluate throughput on the demo run (episodes/s), and the three baselines' driving rate (actions/s).

The reference for the replayed collision intensity is one plain `replay_one` per predicted step; the fast path
replays every step of every episode in one `replay_batch` (2 threads).
"""

from __future__ import annotations

import math
import tempfile
import time
from pathlib import Path

from benchmarks.demo_run import built_demo_run

import numpy as np


def _plain_intensity(rm, poses: np.ndarray) -> np.ndarray:
    from sagebench.evaluation.intensity import blocked_fraction
    from sagebench.replay.physics import replay_one

    c = [0.0]
    for a, b in zip(poses[:-1, :2], poses[1:, :2]):
        if np.linalg.norm(b - a) < rm.config.waypoint_tolerance:
            c.append(0.0)
            continue
        yaw = math.atan2(b[1] - a[1], b[0] - a[0])
        end = replay_one(rm, np.array([[*a, rm.floor_z, yaw], [*b, rm.floor_z, yaw]])).poses[-1, :2]
        c.append(float(blocked_fraction(a[None], b[None], end[None], min_step=rm.config.waypoint_tolerance)[0]))
    return np.array(c)


def run() -> list[dict]:
    from sagebench.evaluation.intensity import replay_intensity
    from sagebench.evaluation.predictions import Prediction, read_predictions, write_predictions
    from sagebench.settings.evaluate import STEP_REPLAY
    from sagebench.stages.evaluate import evaluate
    from sagebench.stages.rollout import BaselineConfig, run_baseline
    from sagebench.replay.scene_model import open_replay_model

    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        run_dir = built_demo_run(Path(tmp))
        preds = {}
        for agent in ("oracle", "straight", "random"):
            preds[agent] = Path(tmp) / f"{agent}.jsonl"
            start = time.perf_counter()
            result = run_baseline(run_dir, preds[agent], BaselineConfig(agent_name=agent))
            s = time.perf_counter() - start
            rows.append({"name": f"baseline {agent}", "reference": "-", "seconds": s, "speed-up": "",
                         "rate": f"{result.actions / s:.0f} actions/s",
                         "notes": f"{result.episodes} episodes, {result.actions} actions"})
        for agent in ("oracle", "random"):
            start = time.perf_counter()
            result = evaluate(run_dir, preds[agent])
            s = time.perf_counter() - start
            n = len(result.scores)
            rows.append({"name": f"evaluate {agent} (intensities given)", "reference": "-", "seconds": s,
                         "speed-up": "", "rate": f"{n / s:.0f} episodes/s", "notes": f"{n} episodes"})
        bare = Path(tmp) / "random_poses.jsonl"
        loaded = [p for _, p in read_predictions(preds["random"])]
        write_predictions(bare, [Prediction(episode_id=p.episode_id, poses=p.poses, stopped=p.stopped) for p in loaded])
        start = time.perf_counter()
        result = evaluate(run_dir, bare)
        s = time.perf_counter() - start
        n = len(result.scores)
        rows.append({"name": "evaluate random (intensities replayed)", "reference": "-", "seconds": s, "speed-up": "",
                     "rate": f"{n / s:.0f} episodes/s", "notes": f"{sum(len(p.poses) - 1 for p in loaded)} steps"})

        rm = open_replay_model(run_dir, "demo_apartment_0", replay=STEP_REPLAY)
        sample = [np.asarray(p.poses) for p in loaded[:40]]
        steps = sum(len(p) - 1 for p in sample)
        start = time.perf_counter()
        reference = [_plain_intensity(rm, p) for p in sample]
        ref_s = time.perf_counter() - start
        rows.append({"name": "replayed intensity, replay_one per step", "reference": "-", "seconds": ref_s,
                     "speed-up": 1.0, "rate": f"{steps / ref_s:.0f} steps/s", "notes": f"{steps} steps, reference"})
        start = time.perf_counter()
        fast = replay_intensity(rm, sample, threads=2)
        s = time.perf_counter() - start
        assert all(np.allclose(a, b, atol=1e-12) for a, b in zip(fast, reference))
        rows.append({"name": "replayed intensity, one replay_batch (2 threads)", "reference": "replay_one per step",
                     "seconds": s, "speed-up": ref_s / s, "rate": f"{steps / s:.0f} steps/s",
                     "notes": "same values"})
    return rows
