"""End-to-end gen-trajectories throughput on the demo scene, one process (one core).

Times `generate_scene` (read maps, name targets, sample pairs, A*, shortcut, instructions, Parquet
shards, paths.png) and, inside it, sampling alone; the reference is the issue's target of 500
trajectory-instruction pairs per second per core.
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

TARGET_PAIRS_PER_S = 500.0


def run() -> list[dict]:
    from sagebench.astar.sampling import sample_trajectories
    from sagebench.scene.synth import write_synth_scene
    from sagebench.stages.build_scene import build_scene
    from sagebench.episodes.targets import scene_targets
    from sagebench.stages.gen_trajectories import GenTrajectoriesConfig, generate_scene, read_scene_inputs

    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        write_synth_scene(Path(tmp) / "scene", seed=0)
        scene_dir = build_scene(Path(tmp) / "scene", Path(tmp) / "run").out_dir
        generate_scene(scene_dir, Path(tmp) / "warm", GenTrajectoriesConfig(per_scene=5))  # JIT load, imports
        for per_scene in (200, 1500):
            config = GenTrajectoriesConfig(per_scene=per_scene)
            spec, smap, grid, _ = read_scene_inputs(scene_dir)
            targets, _ = scene_targets(spec, smap)
            t0 = time.perf_counter()
            sampled = sample_trajectories(grid, targets, spec.scene_id, config)
            t_sample = time.perf_counter() - t0
            t0 = time.perf_counter()
            result = generate_scene(scene_dir, Path(tmp) / f"out{per_scene}", config)
            seconds = time.perf_counter() - t0
            rate = result.rows / seconds
            rows.append({
                "name": f"episodes demo scene, --per-scene {per_scene}",
                "reference": f"target {TARGET_PAIRS_PER_S:.0f} pairs/s/core",
                "seconds": seconds,
                "pairs/s/core": rate,
                "speed-up": rate / TARGET_PAIRS_PER_S,
                "notes": (f"{result.trajectories} trajectories, {result.rows} pairs; sampling alone "
                          f"{t_sample:.3f} s for {sampled.pairs_tried} pairs tried"),
            })
    return rows


if __name__ == "__main__":
    for row in run():
        print(row)
