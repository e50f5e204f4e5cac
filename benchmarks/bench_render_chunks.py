"""Agent-view frames (224x224, the size VLN models take) of the demo scene: chunk-culled vs projecting everything."""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

import numpy as np

from sagebench.render.camera import agent_camera
from sagebench.render.chunks import pack, visible_index
from sagebench.render.splat_render import render, render_packed
from sagebench.scene.loader import load_scene
from sagebench.scene.synth import write_synth_scene
from sagebench.settings.build_scene import SplatConfig
from sagebench.splats.scene import sampled_gaussians

POSES = [(5.5, 4.5, 0.4), (9.0, 6.0, -2.2), (2.0, 2.0, 0.6), (7.0, 5.5, 0.3), (10.5, 4.0, 2.6)]
SIZE = 224


def demo_gaussians():
    """build-scene's Gaussians of the demo apartment (seed 0), about 316 k."""
    with tempfile.TemporaryDirectory() as tmp:
        write_synth_scene(Path(tmp) / "scene", seed=0)
        return sampled_gaussians(load_scene(Path(tmp) / "scene"), SplatConfig(), seed=0)


def _median(fn, repeats: int = 3) -> float:
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return float(np.median(times))


def run() -> list[dict]:
    g = demo_gaussians()
    start = time.perf_counter()
    packed = pack(g)
    pack_s = time.perf_counter() - start
    cams = [agent_camera(x, y, yaw, width=SIZE, height=SIZE) for x, y, yaw in POSES]
    render(packed.gaussians, cams[0])
    render_packed(packed, cams[:1])  # load the compiled kernels
    plain = float(np.median([_median(lambda c=c: render(packed.gaussians, c)) for c in cams]))
    culled = float(np.median([_median(lambda c=c: render_packed(packed, [c])) for c in cams]))
    batch = _median(lambda: render_packed(packed, cams)) / len(cams)
    kept = np.mean([len(visible_index(packed, c)) / g.count for c in cams])
    name = f"{SIZE}x{SIZE} frame, demo scene {g.count / 1e3:.0f} k Gaussians"
    return [
        {"name": name + ", every Gaussian projected", "reference": "-", "seconds": plain, "speed-up": 1.0,
         "notes": f"median over {len(cams)} views x 3"},
        {"name": name + ", chunk-culled", "reference": "every Gaussian projected", "seconds": culled,
         "speed-up": plain / culled, "notes": f"{packed.chunks} chunks; {kept:.0%} of Gaussians projected (mean)"},
        {"name": name + f", {len(cams)} cameras per call", "reference": "every Gaussian projected", "seconds": batch,
         "speed-up": plain / batch, "notes": "per frame"},
        {"name": "pack (once per scene)", "reference": "-", "seconds": pack_s, "speed-up": 1.0, "notes": ""},
    ]


if __name__ == "__main__":
    for row in run():
        print(row)
