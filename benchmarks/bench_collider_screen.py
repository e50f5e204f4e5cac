"""Colliders of a seeded sample of real catalogue models, each at its catalogue size standing on the floor: agent-band
error (worst, median, objects over the tolerance), parts and CPU seconds per model, per `--colliders` mode.

Where `bench colliders` measures the one furnished scene, this screens models the scene never picks. CPU seconds
count this process and the piece workers (bench_colliders._cpu_seconds). `python -m benchmarks collider_screen`;
SAGEBENCH_SCREEN_MODES (comma-separated, default balanced) and SAGEBENCH_SCREEN_N (default 40) pick what runs.
"""

from __future__ import annotations

import os
import statistics
import time

import numpy as np

from benchmarks.bench_colliders import FIXTURE_CATALOGUE, SYSTEM_CATALOGUE, _cpu_seconds

SEED = 0


def sample_entries(catalogue, n: int, seed: int = SEED) -> list:
    """n catalogue entries drawn without replacement by a seeded generator, in catalogue order."""
    pick = np.random.default_rng(seed).choice(len(catalogue.entries), size=min(n, len(catalogue.entries)),
                                              replace=False)
    return [catalogue.entries[i] for i in sorted(pick)]


def screen(mode: str, entries: list, catalogue) -> list[dict]:
    """Per model: name, band error cm, parts, merged parts, CPU s, wall s (no cache: every piece decomposed)."""
    from sagebench.collider_export.coacd_cache import PartCache
    from sagebench.collider_export.decompose import decompose_meshes
    from sagebench.collider_export.methods import band_error_cm
    from sagebench.settings.export_usd import ColliderSettings
    from sagebench.settings.shared import AgentConfig

    settings = ColliderSettings(mode=mode)
    band = AgentConfig().band  # each model standing on a floor at z = 0
    out = []
    for entry in entries:
        mesh = catalogue.load_model(entry)
        v, f = np.asarray(mesh.vertices, dtype=np.float64), np.asarray(mesh.faces, dtype=np.int64)
        start, cpu = time.perf_counter(), _cpu_seconds()
        (mc,) = decompose_meshes({entry.name: (v, f)}, settings, cache=PartCache(None), workers=1, band=band).values()
        cpu, wall = _cpu_seconds() - cpu, time.perf_counter() - start
        out.append({"model": f"{entry.number} {entry.name}", "band cm": band_error_cm(v, f, mc.parts, band),
                    "parts": len(mc.parts), "merged": mc.merged, "CPU s": cpu, "wall s": wall})
    return out


def run() -> list[dict]:
    from sagebench.scene.furniture import Catalogue
    from sagebench.ui import SETTINGS

    catalogue = Catalogue(SYSTEM_CATALOGUE if SYSTEM_CATALOGUE.is_file() else FIXTURE_CATALOGUE)
    entries = sample_entries(catalogue, int(os.environ.get("SAGEBENCH_SCREEN_N", "40")))
    rows = []
    SETTINGS.quiet = True
    for mode in os.environ.get("SAGEBENCH_SCREEN_MODES", "balanced").split(","):
        load = os.getloadavg()[0]
        models = screen(mode, entries, catalogue)
        band = [m["band cm"] for m in models]
        over = [m for m in models if m["band cm"] > 2.0]
        rows.append({"name": f"--colliders {mode}", "models": len(models), "worst band cm": max(band),
                     "median band cm": statistics.median(band), "over 2 cm": len(over),
                     "most parts": max(m["parts"] for m in models),
                     "CPU s": sum(m["CPU s"] for m in models), "max CPU s": max(m["CPU s"] for m in models),
                     "notes": f"{catalogue.source.name}, seed {SEED}; load average {load:.1f} before, "
                              f"{os.getloadavg()[0]:.1f} after"})
        rows += [{"name": f"  {mode} over: {m['model']}", "worst band cm": m["band cm"], "most parts": m["parts"],
                  "CPU s": m["CPU s"], "notes": f"{m['merged']} parts merged away"} for m in over]
    SETTINGS.quiet = False
    return rows
