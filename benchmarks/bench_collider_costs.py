"""export-usd's fixed costs on the furnished scene of `bench colliders`: the command cold and warm (wall, CPU
seconds of it and of every process it started, load average), and the quality measure's hot paths against
their plain references on the scene's own meshes and colliders.

CPU seconds are what a loaded machine inflates least: the command runs under a parent that adopts its orphans
(PR_SET_CHILD_SUBREAPER), so the fork server and the piece workers it reaped are counted too.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from benchmarks.bench_colliders import FIXTURE_CATALOGUE, SYSTEM_CATALOGUE

WORKERS = 2

# run argv[1:], adopt its orphans, reap all of them, print {"rc", "wall", "cpu"} (cpu: user + sys of the whole tree)
_TREE = """
import ctypes, json, os, resource, subprocess, sys, time
ctypes.CDLL(None).prctl(36, 1, 0, 0, 0)
start = time.perf_counter()
rc = subprocess.call(sys.argv[1:], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
wall = time.perf_counter() - start
while True:
    try:
        os.wait()
    except ChildProcessError:
        break
ru = resource.getrusage(resource.RUSAGE_CHILDREN)
print(json.dumps({"rc": rc, "wall": wall, "cpu": ru.ru_utime + ru.ru_stime}))
"""


def _command(argv: list[str]) -> dict:
    """wall and CPU seconds of a command and every process it started, and the load average before it."""
    load = os.getloadavg()[0]
    out = json.loads(subprocess.run([sys.executable, "-c", _TREE, *argv], capture_output=True, text=True,
                                    check=True).stdout)
    if out["rc"] != 0:
        raise RuntimeError(f"{' '.join(argv)}: exit {out['rc']}")
    return out | {"load": load}


def _cpu_seconds(fn) -> tuple[float, float, object]:
    """(wall s, CPU s of this process, result) of fn()."""
    start, cpu = time.perf_counter(), time.process_time()
    result = fn()
    return time.perf_counter() - start, time.process_time() - cpu, result


def run() -> list[dict]:
    import numpy as np
    import trimesh

    from sagebench.collider_export.quality import (
        _distances, _inside, inside_reference, measure_objects, part_planes, sample_surface,
    )
    from sagebench.scene.loader import door_pose, load_scene
    from sagebench.scene.synth import write_synth_scene
    from sagebench.settings.export_usd import ColliderSettings
    from sagebench.stages.build_scene import build_scene
    from sagebench.collider_export.scene_export import local_meshes
    from sagebench.stages.export_usd import agent_band, part_cache
    from sagebench.collider_export.decompose import decompose_meshes
    from sagebench.ui import SETTINGS

    catalogue = SYSTEM_CATALOGUE if SYSTEM_CATALOGUE.is_file() else FIXTURE_CATALOGUE
    cli = Path(sys.executable).parent / "sagebench"
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        write_synth_scene(tmp / "scene", seed=0, furniture=catalogue)
        SETTINGS.quiet = True
        build_scene(tmp / "scene", tmp / "run")
        argv = [str(cli), "export-usd", str(tmp / "run"), "--workers", str(WORKERS), "--cache-dir", str(tmp / "cache"),
                "--quiet"]
        cold, warm = _command(argv), _command(argv)
        for name, m, ref in (("cold", cold, None), ("warm", warm, cold)):
            rows.append({"name": f"sagebench export-usd --workers {WORKERS}, {name} (balanced)",
                         "reference": "cold" if ref else "-", "seconds": m["wall"],
                         "speed-up": ref["wall"] / m["wall"] if ref else "",
                         "notes": f"{catalogue.name}; CPU {m['cpu']:.1f} s (all processes); load average "
                                  f"{m['load']:.1f} on {os.cpu_count()} cores"})

        scene_dir = tmp / "run" / "scenes" / load_scene(tmp / "scene").spec.scene_id
        scene, band = load_scene(scene_dir), agent_band(scene_dir)
        local = local_meshes(scene)
        colliders = decompose_meshes(local, ColliderSettings(), cache=part_cache(tmp / "cache"), workers=WORKERS,
                                     band=band)
        measured = {n: mc.parts for n, mc in colliders.items() if mc.pieces}
        placed = [(o.instance_id, o.mesh, o.transform.as_matrix() if o.door is None
                   else door_pose(o.door) @ o.transform.as_matrix()) for o in scene.spec.objects if o.mesh in measured]
        one = _cpu_seconds(lambda: measure_objects(placed, local, measured, band, workers=1))
        two = _cpu_seconds(lambda: measure_objects(placed, local, measured, band, workers=WORKERS))
        assert one[2] == two[2]
        rows.append({"name": f"collider quality of {len(placed)} objects, 1 process", "reference": "-",
                     "seconds": one[0], "speed-up": "", "notes": f"CPU {one[1]:.1f} s"})
        rows.append({"name": f"collider quality, {WORKERS} processes", "reference": "1 process", "seconds": two[0],
                     "speed-up": one[0] / two[0], "notes": "same figures (asserted)"})

        rng = np.random.default_rng(0)
        cases = []  # (source mesh, its surface points, its collider's parts)
        for name, parts in measured.items():
            source = trimesh.Trimesh(*local[name], process=False)
            cases.append((source, sample_surface(source.vertices, source.faces, 1500, rng)[0], parts))
        planes = [(pts, part_planes(p)) for _, pts, parts in cases for p in parts]
        fast = _cpu_seconds(lambda: [_inside(pts, pl) for pts, pl in planes])
        slow = _cpu_seconds(lambda: [inside_reference(pts, pl) for pts, pl in planes])
        rows.append({"name": f"inside-a-part test, {len(planes)} parts x 1500 points (reference: every plane)",
                     "reference": "-", "seconds": slow[0], "speed-up": "", "notes": "numpy, [N, F] at once"})
        rows.append({"name": "inside-a-part test (numba, stops at the first plane outside)", "reference": "every plane",
                     "seconds": fast[0], "speed-up": slow[0] / fast[0], "notes": ""})
        fast = _cpu_seconds(lambda: [_distances(source, pts) for source, pts, _ in cases])
        slow = _cpu_seconds(lambda: [trimesh.proximity.closest_point(source, pts)[1] for source, pts, _ in cases])
        faces = sum(len(source.faces) for source, _, _ in cases)
        rows.append({"name": f"point-to-surface distances, {len(cases)} meshes ({faces} triangles) x 1500 points",
                     "reference": "-", "seconds": slow[0], "speed-up": "", "notes": "trimesh.proximity.closest_point"})
        rows.append({"name": "point-to-surface distances (R-tree from arrays)", "reference": "trimesh",
                     "seconds": fast[0], "speed-up": slow[0] / fast[0],
                     "notes": f"max difference {max(np.abs(a - b).max() for a, b in zip(fast[2], slow[2])):.1e} m"})
        SETTINGS.quiet = False
    return rows
