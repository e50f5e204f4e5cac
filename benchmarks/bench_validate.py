"""Validated trajectories per second on the demo scene: batched rollout replay (2 threads) vs the plain loop."""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

from benchmarks.demo_run import built_demo_run


def run() -> list[dict]:

    from sagebench.episodes.load import read_trajectories
    from sagebench.replay.physics import replay_batch, replay_one
    from sagebench.replay.scene_model import open_replay_model
    from sagebench.settings.validate import ValidateConfig
    from sagebench.stages.validate import validate_scene
    from sagebench.validation.checks import judge

    with tempfile.TemporaryDirectory() as tmp:
        run_dir = built_demo_run(Path(tmp))
        trajs = read_trajectories(run_dir / "episodes" / "demo_apartment_0")
        config = ValidateConfig()
        rm = open_replay_model(run_dir, "demo_apartment_0", replay=config.replay)
        paths = [t.reference_path for t in trajs]
        n = len(paths)

        def verdicts(records):
            return [judge(r, t.reference_path, t.goal, goal_radius=t.goal_radius,
                          geodesic_distance=t.geodesic_distance, timestep=rm.timestep) for r, t in zip(records, trajs)]

        rows = []
        start = time.perf_counter()
        reference = verdicts([replay_one(rm, p) for p in paths])
        ref_s = time.perf_counter() - start
        rows.append({"name": "replay + verdict, plain mj_step loop", "reference": "-", "seconds": ref_s,
                     "speed-up": 1.0, "trajectories/s": n / ref_s, "notes": f"{n} trajectories, reference"})
        for threads in (1, 2):
            start = time.perf_counter()
            fast = verdicts(replay_batch(rm, paths, threads=threads))
            s = time.perf_counter() - start
            assert [v.reasons for v in fast] == [v.reasons for v in reference]
            rows.append({"name": f"replay + verdict, rollout batch ({threads} thread{'s' * (threads > 1)})",
                         "reference": "plain loop", "seconds": s, "speed-up": ref_s / s, "trajectories/s": n / s,
                         "notes": f"{sum(v.passed for v in fast)}/{n} pass, {sum(v.steps for v in fast)} steps"})
        start = time.perf_counter()
        result = validate_scene(run_dir, "demo_apartment_0", config)
        s = time.perf_counter() - start
        rows.append({"name": "validate stage (3 x 3 spot-check frames, files)", "reference": "-", "seconds": s,
                     "speed-up": "", "trajectories/s": n / s, "notes": result.summary().split(" -> ")[0]})
    return rows
