"""build-scene on the demo apartment and on 2 x 2 and 3 x 3 tilings of it (4x and 9x the floor area and objects).

Rows: the whole stage (load, top-down maps, PNG, Gaussians: everything build-scene writes) in CPU seconds of this
process, against the same stage with the passage search as it was before issue 40 (`BEFORE`'s passages.py, read
from git history), run alternately on the same scene, with whether the two wrote byte-identical files, and the
growth against one tile; and the vectorised conservative rasteriser against its shapely reference on the demo's
band-clipped triangles.
"""

from __future__ import annotations

import hashlib
import json
import tempfile
import time
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from benchmarks.history import module_at
from sagebench.fileio import dumps_json, write_bytes
from sagebench.scene.loader import load_scene
from sagebench.scene.synth import write_synth_scene
from sagebench.stages.build_scene import build_scene
from sagebench.topdown import builder
from sagebench.topdown.builder import BuildSceneConfig
from sagebench.topdown.footprints import mesh_parts
from sagebench.topdown.occupancy import clip_to_band
from sagebench.topdown.raster import Grid, touched_cells, touched_cells_reference

TILE = (12.0, 8.2)  # m between tiled copies: the demo (seed 0) spans 11.7 x 7.9 m
BEFORE = "5c3adc2"  # the passage search before issue 40: tree and squares rebuilt, every cell searched, each step
TILINGS = {1: 2, 4: 2, 9: 1}  # tiles -> alternated runs of each version (the best kept)


def write_tiled_scene(dest: Path, sources: list[Path], side: int) -> Path:
    """One scene made of demo apartments side by side, `side` to a row (rooms renamed, instance ids renumbered)."""
    rooms, objects = [], []
    for k, src in enumerate(sources):
        scene = load_scene(src)
        dx, dy = TILE[0] * (k % side), TILE[1] * (k // side)
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
    rows = -(-len(sources) // side)
    tiled = spec.model_copy(update={"scene_id": f"demo_tiled_{side}x{rows}", "rooms": rooms, "objects": objects})
    write_bytes(dest / "scene.json", dumps_json(tiled.model_dump(mode="json", exclude_defaults=True)).encode())
    return dest


def _best(fn, repeat: int) -> float:
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return min(times)


def _cpu(fn) -> float:
    start = time.process_time()
    fn()
    return time.process_time() - start


@contextmanager
def _passages_before():
    """build-scene with `BEFORE`'s passages.py in place of today's (the rest of the stage as it is)."""
    module = module_at(BEFORE, "sagebench/topdown/passages.py")
    today = builder.open_passages
    builder.open_passages = module.open_passages
    try:
        yield
    finally:
        builder.open_passages = today


def _digest(run: Path) -> str:
    files = sorted(p for p in (run / "scenes").rglob("*") if p.is_file())
    return hashlib.sha256(b"".join(p.relative_to(run).as_posix().encode() + p.read_bytes() for p in files)).hexdigest()


def _scaling_rows(tmp: Path, demo: Path) -> list[dict]:
    rows, config = [], BuildSceneConfig()
    build_scene(demo, tmp / "warm", config)  # imports and compiled kernels loaded before anything is timed
    for tiles, repeat in TILINGS.items():
        side = int(round(tiles ** 0.5))
        scene = demo if tiles == 1 else write_tiled_scene(tmp / f"tiled_{tiles}", [demo] * tiles, side)
        new, old = [], []
        for _ in range(repeat):  # alternated, so both see the same load
            new.append(_cpu(lambda: build_scene(scene, tmp / f"new_{tiles}", config)))
            with _passages_before():
                old.append(_cpu(lambda: build_scene(scene, tmp / f"old_{tiles}", config)))
        same = _digest(tmp / f"new_{tiles}") == _digest(tmp / f"old_{tiles}")
        semantic = json.loads(next((tmp / f"new_{tiles}").rglob("semantic_map.json")).read_text())
        rows.append({"name": f"build-scene, {tiles} demo tile{'s' * (tiles > 1)} ({side}x{-(-tiles // side)})",
                     "reference": f"passages.py at {BEFORE}", "CPU s": min(new), "reference CPU s": min(old),
                     "speed-up": min(old) / min(new), "x 1 tile": min(new) / rows[0]["CPU s"] if rows else 1.0,
                     "identical files": "yes" if same else "NO",
                     "notes": f"{len(semantic['instances'])} objects, {semantic['shape'][1]}x{semantic['shape'][0]} "
                              f"cells, navigable {semantic['navigable_area_m2']:.0f} m^2"})
    return rows


def run() -> list[dict]:
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        demo = tmp / "demo_apartment_0"
        write_synth_scene(demo, seed=0)
        rows = _scaling_rows(tmp, demo)
        scene = load_scene(demo)
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
