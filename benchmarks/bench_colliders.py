"""export-usd on the demo apartment furnished with real Sweet Home 3D models: cold/warm time and collider quality
per `--colliders` mode, then the balanced export validated (every trajectory replayed).

Uses Debian's sweethome3d-furniture CC0 catalogue when it is installed (apt-get install
sweethome3d-furniture), else the seven fixture models in tests/fixtures/sh3d_cc0.
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import tempfile
import time
from pathlib import Path

SYSTEM_CATALOGUE = Path("/usr/share/sweethome3d/furniture/BlendSwap-CC-0.sh3f")
FIXTURE_CATALOGUE = Path(__file__).resolve().parent.parent / "tests" / "fixtures" / "sh3d_cc0"
MODES = {"fast": None, "balanced": None, "quality": 3.0}  # mode -> piece budget (s; None = the default)
WORKERS = 2


def _export(run_dir: Path, cache: Path, mode: str, budget: float | None) -> tuple[float, object, str]:
    """(seconds, ExportResult, stderr text) of one export-usd."""
    from sagebench.stages.export_usd import export_usd, make_config

    err = io.StringIO()
    start = time.perf_counter()
    config = make_config(colliders=mode, piece_budget=budget, workers=WORKERS)
    with contextlib.redirect_stderr(err):
        (result,) = export_usd(run_dir, config=config, cache_dir=cache)
    return time.perf_counter() - start, result, err.getvalue()


def _quality_notes(scene_dir: Path, max_parts: int) -> str:
    index = json.loads((scene_dir / "colliders" / "colliders.json").read_text())
    measured = [o for o in index["objects"] if o["quality"]]
    band = [max(o["quality"]["band_over_cm"], o["quality"]["band_under_cm"]) for o in measured]
    surf = [o["quality"]["to_source_max_cm"] for o in measured]
    worst = max(measured, key=lambda o: max(o["quality"]["band_over_cm"], o["quality"]["band_under_cm"]))
    over_parts = sum(len(o["parts"]) > max_parts for o in index["objects"])
    return (f"{len(measured)} objects measured: band error max {max(band):.1f} cm ({worst['name']}), "
            f"{sum(b > 2.0 for b in band)} over 2 cm, median {sorted(band)[len(band) // 2]:.1f} cm; surface max "
            f"{max(surf):.1f} cm; most parts {max(len(o['parts']) for o in index['objects'])} "
            f"({over_parts} objects over {max_parts})")


def run() -> list[dict]:
    from sagebench.scene.loader import load_scene
    from sagebench.scene.synth import write_synth_scene
    from sagebench.stages.build_scene import build_scene
    from sagebench.stages.export_usd import ExportConfig
    from sagebench.stages.gen_trajectories import GenTrajectoriesConfig, gen_trajectories
    from sagebench.stages.validate import validate_run
    from sagebench.ui import SETTINGS

    catalogue = SYSTEM_CATALOGUE if SYSTEM_CATALOGUE.is_file() else FIXTURE_CATALOGUE
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        write_synth_scene(tmp / "scene", seed=0, furniture=catalogue)
        spec = load_scene(tmp / "scene").spec
        models = [o.attributes["asset"] for o in spec.objects if "asset" in o.attributes]
        SETTINGS.quiet = True
        build_scene(tmp / "scene", tmp / "run")
        scene_dir = tmp / "run" / "scenes" / spec.scene_id
        max_parts = ExportConfig().colliders.max_parts
        for mode, budget in MODES.items():
            cache = tmp / f"cache-{mode}"
            load = os.getloadavg()[0]
            cold, res, err = _export(tmp / "run", cache, mode, budget)
            warm, _, _ = _export(tmp / "run", cache, mode, budget)
            made = ", ".join(f"{m} {n}" for m, n in sorted(res.methods.items()))
            rows.append({
                "name": f"export-usd --colliders {mode}, cold", "reference": "-", "seconds": cold,
                "speed-up": "", "notes": f"{catalogue.name}: {len(models)} real models ({len(set(models))} "
                f"different); pieces {made}; {err.count('budget; using')} stopped at the "
                f"{budget or ExportConfig().colliders.piece_budget_s:g} s budget; {WORKERS} workers; load average {load:.1f}"})
            rows.append({"name": f"export-usd --colliders {mode}, warm", "reference": "cold", "seconds": warm,
                         "speed-up": cold / warm, "notes": _quality_notes(scene_dir, max_parts)})
        _export(tmp / "run", tmp / "cache-balanced", "balanced", None)
        gen_trajectories(tmp / "run", GenTrajectoriesConfig(per_scene=200))
        start = time.perf_counter()
        (report,) = validate_run(tmp / "run")
        rows.append({"name": "validate (balanced colliders)", "reference": "-", "seconds": time.perf_counter() - start,
                     "speed-up": "", "notes": report.summary().split(" -> ")[0]})
        SETTINGS.quiet = False
    return rows
