"""import-interiorgs: the cost of importing 1 M and 3 M Gaussians, and how the object geometry method compares.

Scenes: synth apartments written as InteriorGS folders by the test fixture writer (tests/interiorgs_fixture.py,
which follows the dataset card and SAGE-3D's code). Cost rows: the whole import of a folder of about 1 M and 3 M
Gaussians (read, assign, surfaces, occupancy check, write), with SH degree 0 and 3 (random higher coefficients
added, written in the compressed layout's `sh` element), each in a fresh process: its user + system CPU seconds
and its peak RSS (the interpreter and imports included), per million Gaussians too (CPU past the start-up) beside
the target (issue 38: at most 6 CPU-s and 1 GB, 0.93 GiB, per million), and on the 3 M rows how both grew from
the 1 M import of the same SH degree, per million more Gaussians (the start-up and other fixed costs cancel).
Method rows (demo apartment, seed 0): the navigable map's IoU with the mesh-built one, the median and mean
per-object IoU of the cells each object blocks in the agent's band, the IoU of the L-sofa's semantic footprint, and the
convex parts, and the mean share of the free space under the tops of desks and tables (their knee space: inside
their tightest box, 3 cm clear of the mesh) that the geometry fills; for the voxel-box hulls sagebench uses, one convex hull of each object's Gaussians, and the
labelled box itself.
"""

from __future__ import annotations

import dataclasses
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import trimesh

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from interiorgs_fixture import (  # noqa: E402
    band_footprint_ious, compressed_ply, empty_space_filled, iou, on_grid, write_interiorgs_folder,
)

from sagebench.collider_export.convex import hull_part  # noqa: E402
from sagebench.importers.interiorgs import import_interiorgs, write_imported  # noqa: E402
from sagebench.importers.interiorgs_structure import box_mesh  # noqa: E402
from sagebench.scene.assets import CATALOGUE, table  # noqa: E402
from sagebench.scene.loader import load_scene  # noqa: E402
from sagebench.scene.synth import write_synth_scene  # noqa: E402
from sagebench.settings.build_scene import BuildSceneConfig, SplatConfig
from sagebench.splats.ply import read_ply  # noqa: E402
from sagebench.topdown.builder import compute_topdown  # noqa: E402
from sagebench.topdown.footprints import footprint_reference, mesh_parts  # noqa: E402

TARGET = 1_000_000
PER_MILLION_TARGET = "6 CPU-s, 0.93 GiB"  # issue 38: import <= 6 CPU-s and <= 1 GB peak RSS per million Gaussians
KNEE_SPACE = frozenset(c for c, a in CATALOGUE.items() if a.build is table)  # a top on legs: free space under it


def _load() -> str:
    return " ".join(f"{v:.1f}" for v in os.getloadavg())


def run() -> list[dict]:
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        write_synth_scene(root / "scene", seed=0)
        rows = _methods(root)
        first: dict[int, tuple[float, float, float]] = {}  # SH degree -> the 1 M import's (millions, CPU-s, GiB)
        for millions in (1, 3):
            # densities scaled so that the folder holds about that many Gaussians (the demo's defaults give ~290 k)
            factor = millions * TARGET / 290_000 * 1.02
            folder = root / f"0009_00000{millions}"
            write_interiorgs_folder(root / "scene", folder, splats=SplatConfig(object_density=900 * factor,
                                                                              structure_density=300 * factor))
            for degree in (0, 3):
                if degree:
                    _with_sh_degree_3(folder)
                row, cost = _import_cost(folder, root / f"imported_{millions}_sh{degree}")
                if degree in first:
                    more, cpu, gb = (b - a for a, b in zip(first[degree], cost))
                    row["growth_from_1m"] = f"{cpu / more:.1f} CPU-s, {gb / more:.2f} GiB per million more"
                first.setdefault(degree, cost)
                rows.append(row)
    return rows


def _with_sh_degree_3(folder: Path) -> None:
    """Rewrite the folder's PLY with SH degree 3: random higher coefficients (sd 0.3) after each Gaussian's DC."""
    g = read_ply(folder / "3dgs_compressed.ply")
    rest = np.random.default_rng(0).normal(0.0, 0.3, (g.count, 15, 3)).astype(np.float32)
    g = dataclasses.replace(g, sh=np.concatenate([g.sh, rest], axis=1))
    (folder / "3dgs_compressed.ply").write_bytes(compressed_ply(g))


def _import_cost(folder: Path, out: Path) -> tuple[dict, tuple[float, float, float]]:
    """Import `folder` into `out` in a fresh process: its CPU seconds (all, and past the start-up: interpreter and
    module imports) and its peak RSS (VmHWM: ru_maxrss would carry this process's peak over the exec); the row,
    and (millions of Gaussians, CPU-s past the start-up, GiB)."""
    code = ("import json, re, resource, sys; from pathlib import Path; "
            "from sagebench.importers.interiorgs import import_interiorgs, write_imported; "
            "r0 = resource.getrusage(resource.RUSAGE_SELF); "
            "write_imported(import_interiorgs(Path(sys.argv[1])), Path(sys.argv[2])); "
            "r = resource.getrusage(resource.RUSAGE_SELF); "
            "hwm = int(re.search(r'VmHWM:\\s+(\\d+)', Path('/proc/self/status').read_text()).group(1)); "
            "print(json.dumps([r.ru_utime + r.ru_stime, r0.ru_utime + r0.ru_stime, r.ru_stime - r0.ru_stime, hwm]))")
    t0 = time.perf_counter()
    done = subprocess.run([sys.executable, "-c", code, str(folder), str(out)], capture_output=True, text=True,
                          check=True)
    wall = time.perf_counter() - t0
    cpu, start_up, system, hwm_kb = json.loads(done.stdout.strip().splitlines()[-1])
    g = read_ply(folder / "3dgs_compressed.ply")
    millions, gb = g.count / 1e6, hwm_kb / 2**20
    return {"case": f"import {g.count:,} Gaussians, SH degree {g.sh_degree}", "seconds": round(wall, 1),
            "cpu_s": round(cpu, 1), "start_up_cpu_s": round(start_up, 1), "import_system_s": round(system, 1),
            "peak_rss_gib": round(gb, 2),
            "per_million": f"{(cpu - start_up) / millions:.1f} CPU-s, {gb / millions:.2f} GiB",
            "target_per_million": PER_MILLION_TARGET, "load": _load()}, (millions, cpu - start_up, gb)


def _methods(root: Path) -> list[dict]:
    folder = root / "0001_000000"
    truth = write_interiorgs_folder(root / "scene", folder)
    t0 = time.perf_counter()
    imported = import_interiorgs(folder)
    seconds = time.perf_counter() - t0
    report = imported.report
    label_of = {int(k): int(v["label"]) for k, v in report["instances"].items() if v["label"] is not None}
    ids = imported.gaussians.instance_id
    means = imported.gaussians.means.astype(np.float64)
    objects = {o.instance_id: o for o in imported.spec.objects if o.instance_id in label_of}
    out = []
    for method in ("voxel-box hulls (sagebench)", "one hull per object", "labelled box"):
        meshes = dict(imported.meshes)
        for o in objects.values():
            if method == "one hull per object":
                part = hull_part(means[ids == o.instance_id])
                mesh = trimesh.Trimesh(part.vertices, part.faces, process=False)
            elif method == "labelled box":
                from sagebench.importers.boxes import box_from_corners

                labels = json.loads((folder / "labels.json").read_text())
                lab = next(lb for lb in labels if int(lb["ins_id"]) == label_of[o.instance_id])
                mesh = box_mesh(box_from_corners(np.array([[c["x"], c["y"], c["z"]] for c in lab["bounding_box"]])))
            else:
                continue
            if o.door is not None:  # the mesh stands as the leaf does; scene.json holds it closed
                from sagebench.scene.loader import door_pose

                mesh.apply_transform(np.linalg.inv(door_pose(o.door)))
            meshes[o.mesh] = mesh
        scene_dir = root / f"method{len(out)}"
        write_imported(dataclasses.replace(imported, meshes=meshes), scene_dir)
        scene = load_scene(scene_dir)
        td = compute_topdown(scene, BuildSceneConfig())
        nav = iou(truth.topdown.navigable != 0, on_grid(td.navigable != 0, td.grid, truth.topdown.grid))
        sofa = next(o for o in scene.spec.objects if o.category == "sofa")
        mesh_sofa = truth.scene.meshes[label_of[sofa.instance_id]]
        a, b = footprint_reference(*mesh_parts(mesh_sofa)), footprint_reference(*mesh_parts(scene.meshes[sofa.instance_id]))
        parts = sum(int(mesh_parts(scene.meshes[i])[1].max()) + 1 for i in objects)
        band = band_footprint_ious(truth, scene, label_of)
        knee = [empty_space_filled(truth.scene.meshes[label_of[o.instance_id]], scene.meshes[o.instance_id])
                for o in scene.spec.objects if o.category in KNEE_SPACE and o.instance_id in objects]
        knee = [k for k in knee if k is not None]
        out.append({"case": method, "navigable_iou": round(nav, 4), "median_band_iou": round(float(np.median(band)), 3),
                    "mean_band_iou": round(float(np.mean(band)), 3),
                    "l_sofa_footprint_iou": round(a.intersection(b).area / a.union(b).area, 3),
                    "knee_space_filled": f"{np.mean(knee):.1%} of {len(knee)}" if knee else "none",
                    "object_parts": parts, "seconds": round(seconds, 1) if not out else "", "load": _load()})
    return out


if __name__ == "__main__":
    for row in run():
        print(row)
