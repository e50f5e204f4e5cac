"""export-usd on the demo apartment furnished with real Sweet Home 3D models: cold/warm time, CPU seconds and
collider quality per `--colliders` mode, then the balanced export validated (every trajectory replayed).

CPU seconds are this process's plus the piece workers' (children of multiprocessing's fork server, which reaps
them: its /proc cutime/cstime), so they count the work whatever else loads the machine.

Uses Debian's sweethome3d-furniture CC0 catalogue when it is installed (apt-get install
sweethome3d-furniture), else the eight fixture models in tests/fixtures/sh3d_cc0.
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
MODES = ("fast", "balanced", "quality")
WORKERS = 2


def _cpu_seconds() -> float:
    """User + system CPU of this process and of every piece worker finished so far."""
    from multiprocessing import forkserver

    own = time.process_time()
    pid = forkserver._forkserver._forkserver_pid
    if pid is None:
        return own
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except OSError:
        return own
    return own + sum(int(x) for x in fields[11:15]) / os.sysconf("SC_CLK_TCK")  # utime stime cutime cstime


def _export(run_dir: Path, cache: Path, mode: str) -> tuple[float, float, object, str]:
    """(seconds, CPU seconds, ExportResult, stderr text) of one export-usd."""
    from sagebench.settings.export_usd import ColliderSettings, ExportConfig
    from sagebench.stages.export_usd import export_usd

    err = io.StringIO()
    start, cpu = time.perf_counter(), _cpu_seconds()
    config = ExportConfig(colliders=ColliderSettings(mode=mode), workers=WORKERS)
    with contextlib.redirect_stderr(err):
        (result,) = export_usd(run_dir, config=config, cache_dir=cache)
    return time.perf_counter() - start, _cpu_seconds() - cpu, result, err.getvalue()


def _quality(scene_dir: Path, max_parts: int) -> dict:
    """Worst and median agent-band error, objects over 2 cm, worst surface distance, most parts, objects over budget."""
    index = json.loads((scene_dir / "colliders" / "colliders.json").read_text())
    measured = [o for o in index["objects"] if o["quality"]]
    band = sorted(max(o["quality"]["band_over_cm"], o["quality"]["band_under_cm"]) for o in measured)
    worst = max(measured, key=lambda o: max(o["quality"]["band_over_cm"], o["quality"]["band_under_cm"]))
    return {"worst band cm": band[-1], "median band cm": band[len(band) // 2], "over 2 cm": sum(b > 2.0 for b in band),
            "surface max cm": max(o["quality"]["to_source_max_cm"] for o in measured),
            "most parts": max(len(o["parts"]) for o in index["objects"]),
            "over budget": sum(len(o["parts"]) > max_parts for o in index["objects"]),
            "worst object": worst["name"], "measured": len(measured)}


def run() -> list[dict]:
    from sagebench.scene.loader import load_scene
    from sagebench.scene.synth import write_synth_scene
    from sagebench.settings.export_usd import ExportConfig
    from sagebench.stages.build_scene import build_scene
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
        for mode in MODES:
            cache = tmp / f"cache-{mode}"
            load = os.getloadavg()[0]
            cold, cold_cpu, res, err = _export(tmp / "run", cache, mode)
            warm, warm_cpu, _, _ = _export(tmp / "run", cache, mode)
            q = _quality(scene_dir, max_parts)
            rows.append({
                "name": f"--colliders {mode}", "reference": "balanced", "cold s": cold, "cold CPU s": cold_cpu,
                "warm s": warm, "warm CPU s": warm_cpu, **{k: v for k, v in q.items() if k != "worst object"},
                "notes": f"{catalogue.name}: {len(models)} real models ({len(set(models))} different); pieces "
                f"{', '.join(f'{m} {n}' for m, n in sorted(res.methods.items()))}; worst {q['worst object']}; "
                f"{err.count('warning:')} warnings; {WORKERS} workers; load average {load:.1f} before, "
                f"{os.getloadavg()[0]:.1f} after"})
        _export(tmp / "run", tmp / "cache-balanced", "balanced")
        gen_trajectories(tmp / "run", GenTrajectoriesConfig(per_scene=200))
        start = time.perf_counter()
        (report,) = validate_run(tmp / "run")
        rows.append({"name": "validate (balanced colliders)", "reference": "-", "cold s": time.perf_counter() - start,
                     "notes": report.summary().split(" -> ")[0]})
        base = next(r for r in rows if r["name"] == "--colliders balanced")
        for r in rows[:-1]:
            r["cold CPU vs balanced"] = r["cold CPU s"] / base["cold CPU s"]
        SETTINGS.quiet = False
    return rows
