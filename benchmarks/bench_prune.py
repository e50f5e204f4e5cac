"""Contribution pruning of the demo scene's Gaussians: render speed-up and PSNR loss at 60% and 90%."""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

import numpy as np

from sagebench.render.camera import Camera
from sagebench.render.gaussians import Gaussians
from sagebench.render.splat_render import render
from sagebench.scene.loader import load_scene
from sagebench.scene.synth import write_synth_scene
from sagebench.settings.build_scene import SplatConfig
from sagebench.splats.prune import contribution_scores, mse, prune_lowest, psnr_from_mse
from sagebench.splats.scene import room_views, sampled_gaussians

SCORING_VIEWS = 32  # 320x240, as build-scene's --prune uses by default
HELD_OUT_VIEWS = 8  # 640x480, different random poses


def _frame_seconds(g: Gaussians, cams: list[Camera]) -> float:
    start = time.perf_counter()
    for cam in cams:
        render(g, cam)
    return (time.perf_counter() - start) / len(cams)


def run() -> list[dict]:
    with tempfile.TemporaryDirectory() as tmp:
        write_synth_scene(Path(tmp) / "scene", seed=0)
        scene = load_scene(Path(tmp) / "scene")
    g = sampled_gaussians(scene, SplatConfig(), seed=0)
    scoring = list(room_views(scene, SCORING_VIEWS, seed=0, width=320))
    held_out = [c.scaled(640, 480) for c in room_views(scene, HELD_OUT_VIEWS, seed=99, width=320)]
    render(g, held_out[0])  # load the compiled kernels
    start = time.perf_counter()
    scores = contribution_scores(g, scoring)
    score_s = time.perf_counter() - start
    full = [render(g, cam).rgb for cam in held_out]
    base_s = _frame_seconds(g, held_out)
    rows = [{"name": f"unpruned, {g.count} Gaussians", "reference": "-", "seconds": base_s, "speed-up": 1.0,
             "notes": f"640x480 s/frame over {HELD_OUT_VIEWS} held-out views; scoring {SCORING_VIEWS} views took "
                      f"{score_s:.1f} s"}]
    for fraction in (0.6, 0.9):
        pruned = prune_lowest(g, scores, fraction)
        err = float(np.mean([mse(render(pruned, cam).rgb, ref) for cam, ref in zip(held_out, full)]))
        seconds = _frame_seconds(pruned, held_out)
        rows.append({"name": f"pruned {fraction:.0%} ({pruned.count} left)", "reference": "unpruned",
                     "seconds": seconds, "speed-up": base_s / seconds,
                     "notes": f"PSNR vs unpruned on held-out views {psnr_from_mse(err):.1f} dB"})
    return rows


if __name__ == "__main__":
    for row in run():
        print(row)
