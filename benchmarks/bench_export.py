"""export-usd on the demo scene with a cold and a warm CoACD cache; the convex-piece shortcut vs CoACD."""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

import numpy as np
import trimesh


def _timed(fn):
    start = time.perf_counter()
    out = fn()
    return time.perf_counter() - start, out


def _u_prism() -> trimesh.Trimesh:
    pts = np.array([(0, 0), (0.6, 0), (0.6, 0.1), (0.6, 0.4), (0.45, 0.4), (0.45, 0.1), (0.15, 0.1), (0.15, 0.4),
                    (0, 0.4), (0, 0.1)])
    tris = np.array([(0, 1, 2), (0, 2, 5), (0, 5, 6), (0, 6, 9), (5, 2, 3), (5, 3, 4), (9, 6, 7), (9, 7, 8)])
    return trimesh.creation.extrude_triangulation(pts, tris, 0.3)


def run() -> list[dict]:
    from sagebench.collider_export.coacd_cache import PartCache, run_coacd
    from sagebench.collider_export.decompose import decompose_meshes
    from sagebench.collider_export.pieces import Piece, decompose_pieces
    from sagebench.scene.loader import load_scene, read_mesh
    from sagebench.scene.synth import write_synth_scene
    from sagebench.settings.export_usd import CoacdParams, ColliderSettings
    from sagebench.settings.shared import AgentConfig
    from sagebench.stages.build_scene import build_scene
    from sagebench.stages.export_usd import export_usd
    from sagebench.ui import SETTINGS

    SETTINGS.quiet = True
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        src = tmp / "demo"
        write_synth_scene(src, seed=0)
        build_scene(src, tmp / "run")
        cache = tmp / "cache"
        cold, (res,) = _timed(lambda: export_usd(tmp / "run", cache_dir=cache))
        warm, _ = _timed(lambda: export_usd(tmp / "run", cache_dir=cache))
        note = f"{res.objects} objects, {res.parts} parts ({res.exact_parts} exact), {res.gaussians} Gaussians"
        rows.append({"name": "export-usd demo, cold cache", "reference": "-", "seconds": cold, "speed-up": "",
                     "notes": note})
        rows.append({"name": "export-usd demo, warm cache", "reference": "cold cache", "seconds": warm,
                     "speed-up": cold / warm, "notes": "no concave piece in the demo: the cache is not touched"})

        scene = load_scene(src)
        meshes = {}
        for o in scene.spec.objects:
            if o.mesh not in meshes:
                m = read_mesh(src / o.mesh, src / "scene.json", o.mesh)
                meshes[o.mesh] = (m.vertices, m.faces)
        band = AgentConfig().band  # the demo's floor is at z = 0
        shortcut, _ = _timed(lambda: decompose_meshes(meshes, ColliderSettings(), cache=PartCache(None), band=band))
        chair_name = next(o.mesh for o in scene.spec.objects if o.category == "chair")
        v, f = meshes[chair_name]
        one, parts = _timed(lambda: run_coacd(v, f, CoacdParams()))
        rows.append({"name": f"convex shortcut, all {len(meshes)} demo meshes", "reference": "CoACD on every mesh (est.)",
                     "seconds": shortcut, "speed-up": one * len(meshes) / shortcut,
                     "notes": f"CoACD defaults on the demo chair: {one:.1f} s, {len(parts)} parts; "
                              f"x {len(meshes)} meshes = {one * len(meshes):.0f} s"})

        u = _u_prism()
        params = ColliderSettings(mode="quality", coacd=CoacdParams(preprocess_mode="off"))
        piece = [Piece("u", u.vertices, u.faces, ("coacd",))]
        ucold, _ = _timed(lambda: decompose_pieces(piece, params, cache=PartCache(cache), band=band))
        uwarm, (hit,) = _timed(lambda: decompose_pieces(piece, params, cache=PartCache(cache), band=band))
        rows.append({"name": "CoACD U-prism (preprocess off), cache hit", "reference": "CoACD run", "seconds": uwarm,
                     "speed-up": ucold / uwarm,
                     "notes": f"run {ucold:.2f} s -> {'cache' if hit.cached else hit.method}, {len(hit.parts)} parts"})
    SETTINGS.quiet = False
    return rows
