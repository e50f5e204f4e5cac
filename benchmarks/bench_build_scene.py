"""build-scene on the demo apartment and on a 2 x 2 tiling of it (4x the floor area, 4x the objects).

Rows: the whole stage (load, top-down maps, PNG, plus whatever else build-scene writes) and the
top-down computation alone, each against the demo scene as the reference; and the vectorised
conservative rasteriser against its shapely reference on the demo's band-clipped triangles.
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

import numpy as np

from sagebench.fileio import dumps_json, write_bytes
from sagebench.scene.loader import load_scene
from sagebench.scene.synth import write_synth_scene
from sagebench.stages.build_scene import build_scene
from sagebench.topdown.builder import BuildSceneConfig, compute_topdown
from sagebench.topdown.footprints import mesh_parts
from sagebench.topdown.occupancy import clip_to_band
from sagebench.topdown.raster import Grid, touched_cells, touched_cells_reference

TILE = (12.0, 8.2)  # m between tiled copies: the demo (seed 0) spans 11.7 x 7.9 m


def write_tiled_scene(dest: Path, sources: list[Path]) -> Path:
    """One scene made of 2 x 2 demo apartments side by side (rooms renamed, instance ids renumbered)."""
    rooms, objects = [], []
    for k, src in enumerate(sources):
        scene = load_scene(src)
        dx, dy = TILE[0] * (k % 2), TILE[1] * (k // 2)
        shift = np.eye(4)
        shift[:2, 3] = dx, dy
        for r in scene.spec.rooms:
            rooms.append(r.model_copy(update={"id": f"t{k}_{r.id}", "polygon": [(x + dx, y + dy) for x, y in r.polygon]}))
        for o in scene.spec.objects:
            m = shift @ o.transform.as_matrix()
            update = {
                "instance_id": len(objects) + 1,
                "room_id": f"t{k}_{o.room_id}" if o.room_id else None,
                "transform": o.transform.model_copy(update={"matrix": tuple(tuple(float(v) for v in row) for row in m)}),
            }
            if o.door:
                hx, hy, hz = o.door.hinge
                update["door"] = o.door.model_copy(update={"hinge": (hx + dx, hy + dy, hz)})
            objects.append(o.model_copy(update=update))
            if not (dest / o.mesh).exists():
                write_bytes(dest / o.mesh, (src / o.mesh).read_bytes())
        spec = scene.spec
    tiled = spec.model_copy(update={"scene_id": "demo_tiled_2x2", "rooms": rooms, "objects": objects})
    write_bytes(dest / "scene.json", dumps_json(tiled.model_dump(mode="json", exclude_defaults=True)).encode())
    return dest


def _best(fn, repeat: int) -> float:
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return min(times)


def run() -> list[dict]:
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        demo = tmp / "demo_apartment_0"
        write_synth_scene(demo, seed=0)
        big = write_tiled_scene(tmp / "tiled", [demo] * 4)
        config = BuildSceneConfig()
        scenes = {"demo": demo, "4x demo (2x2 tiles)": big}
        loaded = {name: load_scene(d) for name, d in scenes.items()}
        stage, topdown = {}, {}
        for name, d in scenes.items():
            stage[name] = _best(lambda d=d: build_scene(d, tmp / "run", config), 2)
            topdown[name] = _best(lambda name=name: compute_topdown(loaded[name], config), 3)
        ref = "demo"
        for name in scenes:
            td = compute_topdown(loaded[name], config)
            area = sum(r.navigable_area_m2 for r in td.semantic.rooms)
            notes = (f"{len(loaded[name].spec.objects)} objects, {td.grid.shape[1]}x{td.grid.shape[0]} cells, "
                     f"navigable {area:.0f} m^2")
            rows.append({"name": f"build-scene {name}", "reference": f"build-scene {ref}", "seconds": stage[name],
                         "ratio to reference": stage[name] / stage[ref], "notes": notes})
            rows.append({"name": f"top-down maps {name}", "reference": f"top-down maps {ref}", "seconds": topdown[name],
                         "ratio to reference": topdown[name] / topdown[ref], "notes": "compute_topdown only"})

        scene = loaded["demo"]
        tris = np.concatenate([mesh_parts(scene.meshes[o.instance_id])[0] for o in scene.spec.objects
                               if o.kind not in ("floor", "ceiling")])
        polys, _ = clip_to_band(tris, 0.05, 1.2)
        sample = polys[np.random.default_rng(0).choice(len(polys), size=min(300, len(polys)), replace=False)]
        grid = Grid.covering(sample.reshape(-1, 2).min(0), sample.reshape(-1, 2).max(0), 0.05, 0.1)
        fast = _best(lambda: touched_cells(sample, grid), 5)
        slow = _best(lambda: touched_cells_reference(sample, grid), 1)
        rows.append({"name": "touched_cells (numpy SAT)", "reference": "touched_cells_reference (shapely)",
                     "seconds": fast, "speed-up": slow / fast,
                     "notes": f"{len(sample)} of the demo's {len(polys)} band-clipped triangles"})
    return rows


if __name__ == "__main__":
    for row in run():
        print(row)
