"""GPU check: gsplat's speed on the demo run and its agreement with the CPU renderer, on the GPU at hand.

    python benchmarks/gpu_check.py --run RUN_DIR_OR_TGZ --out DIR [--budget 480] [--dry-run]

RUN is a run directory (or a .tgz of one, as benchmarks/gpu_pack.sh packs the demo run) with episodes and
scenes/<id>/{scene.json, topdown.npz, gaussians.ply, scene.xml, colliders/}. Each section runs in a process of its
own under its own time limit (and within --budget seconds in all); one that fails or runs out of time is reported
and the next one runs. Writes DIR/gpu_check.md (the table), DIR/gpu_check.json (its rows) and DIR/gpu_check.log
(every section's output). Needs no network. --dry-run does everything with the CPU renderer at small sizes (for
machines without a GPU, and the tests).

Sections: device (the card, torch, gsplat, and gsplat's one-time CUDA build, timed), render (gsplat frames/s at
224x224 for 1, 16, 64 and 256 views per call: through sagebench's renderer, float frames back as arrays; the
observations the env takes, uint8 RGB + depth converted on the GPU, back as arrays; and gsplat's rasterization
alone), agreement (PSNR and median depth difference of gsplat against the CPU renderer on 20 demo views, and the
observations against the float frames converted on the host), env (closed-loop steps/s with physics for 1, 16
and 64 batched episodes, gsplat; 16 with the CPU renderer for reference), export (export-training frames/s with gsplat).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import shutil
import subprocess
import sys
import tarfile
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
# What a GPU image brings (the distributions of sagebench's dependencies it has); gpu_pack.sh packs the rest the
# sections import, and a test runs the sections with every other dependency made unimportable.
IMAGE_HAS = ("numpy", "scipy", "numba", "pyarrow", "opencv-python-headless", "torch")
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

import numpy as np  # noqa: E402

TARGETS = {("render", 64): 5000.0, ("env", 64): 2000.0, "psnr": 35.0, "depth": 0.02}
LIMITS = {"device": 300, "render": 120, "agreement": 120, "env": 180, "export": 150}  # seconds per section


class Check:
    """What a section needs: the run, the sizes for a real or a dry run, and the renderer to measure."""

    def __init__(self, run_dir: Path, dry: bool):
        self.run_dir, self.dry = run_dir, dry
        self.size = 32 if dry else 224
        self.views = (1, 4) if dry else (1, 16, 64, 256)
        self.batches = (1, 4) if dry else (1, 16, 64)
        self.agreement_views = 3 if dry else 20
        self.export_episodes = 4 if dry else 64
        self.backend = "cpu" if dry else "gsplat"

    def scene(self):
        """(scene id, packed Gaussians) of the first episode's scene."""
        from sagebench.navsim.world import run_episodes
        from sagebench.render.chunks import pack
        from sagebench.run_layout import GAUSSIANS, run_scene_dir
        from sagebench.splats.ply import read_ply

        sid = run_episodes(self.run_dir)[0][0].scene_id
        return sid, pack(read_ply(run_scene_dir(self.run_dir, sid) / GAUSSIANS))

    def cameras(self, n: int):
        """n agent views at the episodes' starts, turned in 0.4 rad steps (deterministic)."""
        from sagebench.navsim.world import run_episodes
        from sagebench.render.camera import agent_camera

        episodes = run_episodes(self.run_dir)[0]
        floor = _floor(self.run_dir, episodes[0].scene_id)
        return [agent_camera(float(e.start[0]), float(e.start[1]), float(e.start_yaw) + 0.4 * (k // len(episodes)),
                             floor_z=floor, width=self.size, height=self.size)
                for k, e in ((k, episodes[k % len(episodes)]) for k in range(n))]


def _floor(run_dir: Path, scene_id: str) -> float:
    from sagebench.run_layout import SCENE_FILE, run_scene_dir

    return float(json.loads((run_scene_dir(run_dir, scene_id) / SCENE_FILE).read_text()).get("floor_height", 0.0))


def _sync() -> None:
    if "torch" in sys.modules:
        import torch

        if torch.cuda.is_available():
            torch.cuda.synchronize()


def _rate(fn, items_per_call: int, *, min_seconds: float = 1.0, min_calls: int = 3) -> float:
    """Items per second of fn() after one warm-up call, over at least min_calls calls and min_seconds."""
    fn()
    _sync()
    calls, start = 0, time.perf_counter()
    while calls < min_calls or time.perf_counter() - start < min_seconds:
        fn()
        calls += 1
    _sync()
    return items_per_call * calls / (time.perf_counter() - start)


# ---------------------------------------------------------------- sections


def section_device(c: Check) -> Iterator[dict]:
    if c.dry:
        import numba

        yield {"what": "device", "value": "CPU (dry run)", "note": f"numba {numba.__version__}"}
        return
    from importlib import metadata

    from sagebench.render.backends import extensions_dir, load_gsplat

    start = time.perf_counter()
    torch, _ = load_gsplat()
    seconds = time.perf_counter() - start
    props = torch.cuda.get_device_properties(0)
    yield {"what": "device", "value": torch.cuda.get_device_name(0),
           "note": f"{props.total_memory / 2**30:.0f} GiB, torch {torch.__version__}, gsplat "
                   f"{metadata.version('gsplat')}"}
    yield {"what": "gsplat CUDA build (first use) or load", "value": round(seconds, 1), "unit": "s",
           "note": str(extensions_dir())}


def section_render(c: Check) -> Iterator[dict]:
    from sagebench.render.backends import open_renderer

    _, packed = c.scene()
    renderer = open_renderer(packed, c.backend, needs=("rgb", "depth"))
    for v in c.views:
        cams = c.cameras(v)
        fps = _rate(lambda cams=cams: renderer.render(cams), v)
        yield {"what": f"render {c.size}x{c.size}, {v} views per call, frames back as arrays",
               "value": round(fps, 1), "unit": "frames/s", "target": TARGETS.get(("render", v), "")}
        fps = _rate(lambda cams=cams: renderer.observe(cams, ("rgb", "depth")), v)
        yield {"what": f"observations {c.size}x{c.size} (uint8 RGB + depth, as the env takes them), {v} views per "
                       "call, back as arrays", "value": round(fps, 1), "unit": "frames/s",
               "target": TARGETS.get(("render", v), "")}
        if c.backend == "gsplat":
            yield {"what": f"gsplat rasterization alone, {v} views per call (frames left on the GPU)",
                   "value": round(_rate(lambda cams=cams: renderer.rasterize(cams), v), 1), "unit": "frames/s"}


def section_agreement(c: Check) -> Iterator[dict]:
    from sagebench.render.backends import CpuRenderer, open_renderer
    from sagebench.render.observations import observation_arrays

    _, packed = c.scene()
    cams = c.cameras(c.agreement_views)
    renderer = open_renderer(packed, c.backend, needs=("rgb", "depth"))
    gpu = renderer.render(cams)
    cpu = CpuRenderer(packed).render(cams)
    psnr, depth, compared = [], [], []
    for a, b in zip(gpu, cpu):
        mse = float(np.mean((np.clip(a.rgb, 0, 1) - np.clip(b.rgb, 0, 1)) ** 2))
        psnr.append(math.inf if mse == 0 else 10 * math.log10(1.0 / mse))
        both = (a.alpha > 0.5) & (b.alpha > 0.5)
        compared.append(float(both.mean()))
        depth.append(float(np.median(np.abs(a.depth[both] - b.depth[both]))) if both.any() else math.nan)
    note = f"{len(cams)} views {c.size}x{c.size}; depth over pixels opaque (alpha > 0.5) in both, " \
           f"{100 * np.mean(compared):.0f} % of pixels"
    yield {"what": "PSNR gsplat vs CPU, mean over views", "value": round(float(np.mean(psnr)), 2), "unit": "dB",
           "target": TARGETS["psnr"], "note": f"min {min(psnr):.2f} dB"}
    yield {"what": "median abs(depth gsplat - CPU), median over views", "value": round(float(np.nanmedian(depth)), 4),
           "unit": "m", "target": TARGETS["depth"], "note": f"max {np.nanmax(depth):.4f} m; {note}"}
    # the observations as the env gets them (converted where the frames are) against the float frames converted here
    got = renderer.observe(cams, ("rgb", "depth"))
    want = observation_arrays({"rgb": np.stack([f.rgb for f in gpu]), "depth": np.stack([f.depth for f in gpu]),
                               "alpha": np.stack([f.alpha for f in gpu])}, ("rgb", "depth"))
    same = [float(np.mean(got[k] == want[k])) for k in ("rgb", "depth")]
    yield {"what": "observations vs float frames converted on the host: equal values (RGB, depth)",
           "value": f"{100 * same[0]:.2f} %, {100 * same[1]:.2f} %", "target": "100 %",
           "note": f"{len(cams)} views; uint8 RGB + depth from observe() against render()'s frames"}


def section_env(c: Check) -> Iterator[dict]:
    from sagebench.navsim.actions import Action
    from sagebench.navsim.simulator import Simulator
    from sagebench.settings.rollout import EnvConfig

    pattern = [Action.MOVE_FORWARD, Action.MOVE_FORWARD, Action.TURN_LEFT, Action.MOVE_FORWARD, Action.TURN_RIGHT]
    runs = [(b, c.backend) for b in c.batches] + ([] if c.dry else [(16, "cpu")])
    for batch, backend in runs:
        config = EnvConfig(width=c.size, height=c.size, observations=("rgb", "depth"), max_steps=1_000_000,
                           renderer=backend)
        sim = Simulator(c.run_dir, config, threads=min(os.cpu_count() or 1, 16))
        ids = [sim.order[k % len(sim.order)] for k in range(batch)]
        if len(set(ids)) < len(ids):
            ids = list(dict.fromkeys(ids))
        sim.start(ids)
        step = [0]

        def one():
            sim.step([pattern[step[0] % len(pattern)]] * len(ids))
            step[0] += 1

        live = lambda: sum(not s.done for s in sim.slots)  # noqa: E731
        rate = _rate(one, len(ids), min_seconds=2.0)
        yield {"what": f"env steps with physics, {len(ids)} episodes batched, {backend} renderer, "
                       f"RGB + depth {c.size}x{c.size}",
               "value": round(rate, 1), "unit": "steps/s",
               "target": TARGETS.get(("env", batch), "") if backend == c.backend else "",
               "note": f"{live()} of {len(ids)} still running at the end"}


def section_export(c: Check) -> Iterator[dict]:
    import pyarrow.parquet as pq

    from sagebench.settings.export_training import TrainingExportConfig
    from sagebench.training.export import export_training

    with tempfile.TemporaryDirectory() as tmp:
        sub = Path(tmp) / "run"
        shutil.copytree(c.run_dir / "scenes", sub / "scenes")
        left = c.export_episodes
        for part in sorted((c.run_dir / "episodes").rglob("*.parquet")):
            table = pq.read_table(part)
            if left <= 0:
                break
            dest = sub / part.relative_to(c.run_dir)
            dest.parent.mkdir(parents=True, exist_ok=True)
            pq.write_table(table.slice(0, left), dest)
            left -= min(left, table.num_rows)
        config = TrainingExportConfig(width=c.size, height=c.size, renderer=c.backend, batch=c.export_episodes,
                                      episodes_per_shard=c.export_episodes, workers=min(os.cpu_count() or 1, 16))
        result = export_training(sub, Path(tmp) / "out", config)
    yield {"what": f"export-training, {result.episodes} episodes batched, RGB {c.size}x{c.size}, {c.backend}",
           "value": round(result.samples / result.seconds, 1), "unit": "frames/s",
           "note": f"{result.samples} frames in {result.seconds:.1f} s (PNG encoding on one thread)"}


SECTIONS = {"device": section_device, "render": section_render, "agreement": section_agreement,
            "env": section_env, "export": section_export}


# ---------------------------------------------------------------- driver


def _unpack(run: Path, into: Path) -> Path:
    if run.is_dir():
        return run
    with tarfile.open(run) as tar:
        tar.extractall(into, filter="data")
    return into


def _table(rows: list[dict], header: str) -> str:
    lines = [header, "", "| section | measure | value | unit | target | status | note |", "|---|---|---|---|---|---|---|"]
    for r in rows:
        cells = [r["section"], r.get("what", ""), r.get("value", ""), r.get("unit", ""), r.get("target", ""),
                 r.get("status", "ok"), r.get("note", "")]
        lines.append("| " + " | ".join(str(x).replace("|", "/") for x in cells) + " |")
    return "\n".join(lines) + "\n"


def drive(run: Path, out: Path, *, budget: float, dry: bool, sections: list[str]) -> list[dict]:
    out.mkdir(parents=True, exist_ok=True)
    log = open(out / "gpu_check.log", "w", encoding="utf-8")
    start = time.monotonic()
    rows: list[dict] = []
    with tempfile.TemporaryDirectory() as tmp:
        run_dir = _unpack(run, Path(tmp) / "run")
        for name in sections:
            left = budget - (time.monotonic() - start)
            limit = min(LIMITS[name], left)
            if left < 10:
                rows.append({"section": name, "status": "SKIPPED", "note": "no time left in the budget"})
                continue
            result = Path(tmp) / f"{name}.json"
            cmd = [sys.executable, str(Path(__file__).resolve()), "--section", name, "--run", str(run_dir),
                   "--result", str(result), *(["--dry-run"] if dry else [])]
            t0 = time.monotonic()
            log.write(f"\n===== {name} (limit {limit:.0f} s) =====\n")
            log.flush()
            try:
                done = subprocess.run(cmd, stdout=log, stderr=subprocess.STDOUT, timeout=limit,
                                      env={**os.environ, "PYTHONUNBUFFERED": "1"})
                failed = done.returncode != 0 and f"exit status {done.returncode}"
            except subprocess.TimeoutExpired:
                failed = f"timed out after {limit:.1f} s"
            log.write(f"===== {name}: {time.monotonic() - t0:.1f} s =====\n")
            log.flush()
            got = [json.loads(ln) for ln in result.read_text().splitlines()] if result.is_file() else []
            rows += [{"section": name, **r} for r in got]
            if failed:
                rows.append({"section": name, "status": "FAILED", "note": f"{failed}; {_last_error(out)}"})
            print(f"{name}: {'FAILED ' + failed if failed else 'ok'} ({time.monotonic() - t0:.0f} s)", flush=True)
    log.close()
    return rows


def _last_error(out: Path) -> str:
    """The last line of the log that looks like an error, for the table."""
    lines = [ln.strip() for ln in (out / "gpu_check.log").read_text(errors="replace").splitlines() if ln.strip()]
    lines = [ln for ln in lines if not ln.startswith("=====")]
    errors = [ln for ln in lines if "Error" in ln or "error" in ln]
    return (errors or lines or ["no output"])[-1][:300]


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--run", type=Path, required=True)
    p.add_argument("--out", type=Path)
    p.add_argument("--budget", type=float, default=480.0, help="Seconds for all sections together.")
    p.add_argument("--dry-run", action="store_true", help="CPU renderer, small sizes (no GPU needed).")
    p.add_argument("--sections", default=",".join(SECTIONS), help="Comma-separated subset of the sections.")
    p.add_argument("--section", help=argparse.SUPPRESS)
    p.add_argument("--result", type=Path, help=argparse.SUPPRESS)
    a = p.parse_args(argv)
    if a.section:  # one section, in its own process: each row saved as soon as it is measured
        with open(a.result, "a", encoding="utf-8") as fh:
            for row in SECTIONS[a.section](Check(a.run, a.dry_run)):
                fh.write(json.dumps(row, default=str) + "\n")
                fh.flush()
                print(f"  {row.get('what')}: {row.get('value')} {row.get('unit', '')}", flush=True)
        return 0
    if a.out is None:
        p.error("--out is required")
    names = [s for s in a.sections.split(",") if s]
    unknown = sorted(set(names) - set(SECTIONS))
    if unknown:
        p.error(f"unknown sections {unknown}; known: {', '.join(SECTIONS)}")
    start = time.time()
    rows = drive(a.run, a.out, budget=a.budget, dry=a.dry_run, sections=names)
    header = (f"## GPU check ({'dry run on the CPU' if a.dry_run else 'gsplat'}), "
              f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime(start))}, {time.time() - start:.0f} s, "
              f"load {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
    (a.out / "gpu_check.json").write_text(json.dumps(rows, indent=2, default=str) + "\n")
    table = _table(rows, header)
    (a.out / "gpu_check.md").write_text(table)
    print(table, flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
