"""Scale rehearsal: N demo apartments (synth-scene seeds 0..N-1) through `sagebench run` on two local workers,
to check that a long run stays flat in memory and to project SAGE-Bench's size (1,000 scenes, 2 M pairs).

N comes from SAGEBENCH_SCALE_SCENES (default 4; `SAGEBENCH_SCALE_SCENES=20 python -m benchmarks scale` for the
documented figures). Workers live for the whole run, so a leak shows as their resident memory growing: it is
sampled while the run goes and reported when N/4, N/2 and N scenes have passed validate.
"""

from __future__ import annotations

import json
import os
import resource
import tempfile
import threading
import time
from pathlib import Path

from sagebench.pipeline.config import load_run_config
from sagebench.pipeline.kernels import compile_kernels
from sagebench.pipeline.manifest import write_manifest
from sagebench.pipeline.run import run_pipeline
from sagebench.run_layout import MANIFEST, STAMPS
from sagebench.scene.synth import write_synth_scene
from sagebench.ui import SETTINGS

WORKERS = 2
TARGET_SCENES, TARGET_PAIRS, TARGET_CORES = 1000, 2_000_000, 16
PER_EPISODE_STAGES = ("gen_trajectories", "validate")  # their work grows with the pairs (validate replays each)


def _cpu_seconds() -> float:
    """CPU-s of this process and of its children that have ended (run's workers end with the run)."""
    return sum(r.ru_utime + r.ru_stime for r in (resource.getrusage(resource.RUSAGE_SELF),
                                                  resource.getrusage(resource.RUSAGE_CHILDREN)))


def _workers() -> dict[int, tuple[int, int]]:
    """pid -> (VmRSS, VmHWM) in kB of this process's pool workers (spawned: their command line says so)."""
    me, out = str(os.getpid()), {}
    for entry in Path("/proc").iterdir():
        try:
            if not entry.name.isdigit() or (entry / "stat").read_text().rsplit(")", 1)[1].split()[1] != me:
                continue
            if b"spawn_main" not in (entry / "cmdline").read_bytes():
                continue
            fields = dict(line.split(":", 1) for line in (entry / "status").read_text().splitlines())
            out[int(entry.name)] = (int(fields["VmRSS"].split()[0]), int(fields["VmHWM"].split()[0]))
        except (OSError, IndexError, KeyError, ValueError):
            continue  # it ended meanwhile
    return out


class _Sampler(threading.Thread):
    """Every half second: scenes past validate, and the largest resident set and peak of the live workers."""

    def __init__(self, run_dir: Path):
        super().__init__(daemon=True)
        self.run_dir, self.samples, self.pids = run_dir, [], set()
        self.stop = threading.Event()

    def run(self) -> None:
        while not self.stop.wait(0.5):
            live = _workers()
            if live:
                self.pids |= set(live)
                done = len(list((self.run_dir / STAMPS).glob("*/validate.json")))
                self.samples.append((done, max(r for r, _ in live.values()), max(h for _, h in live.values())))

    def at(self, scenes: int) -> tuple[float, float]:
        """(RSS, peak RSS) in MB of the biggest worker in the last sample with at most `scenes` scenes done."""
        _, rss, hwm = max((s for s in self.samples if s[0] <= scenes), default=(0, 0, 0))
        return rss / 1024, hwm / 1024


def run() -> list[dict]:
    SETTINGS.quiet = True
    scenes = int(os.environ.get("SAGEBENCH_SCALE_SCENES", "4"))
    compile_kernels()
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        for seed in range(scenes):
            write_synth_scene(root / "scenes" / f"s{seed}", seed=seed)
        config_path = root / "scale.toml"
        config_path.write_text('scenes = ["scenes/*"]\nout = "out"\ncache_dir = "cache"\n')
        sampler = _Sampler(root / "out")
        sampler.start()
        load, cpu, start = os.getloadavg()[0], _cpu_seconds(), time.perf_counter()
        summary = run_pipeline(load_run_config(config_path, workers=WORKERS), config_path)
        wall, cpu = time.perf_counter() - start, _cpu_seconds() - cpu
        sampler.stop.set()
        sampler.join()
        manifest_cpu, files = _manifest_cost(root / "out")
    return _rows(scenes, summary, cpu, wall, sampler, manifest_cpu, files, load)


def _manifest_cost(run_dir: Path) -> tuple[float, int]:
    """CPU-s to hash the run into its manifest again (what run does last, in the driver), and the files listed."""
    old = json.loads((run_dir / MANIFEST).read_text())
    cpu = time.process_time()
    write_manifest(run_dir, config=old["config"], inputs=old["inputs"], failed=old["failed"])
    return time.process_time() - cpu, len(old["files"])


def _rows(scenes, summary, cpu, wall, sampler, manifest_cpu, files, load) -> list[dict]:
    per_scene, pairs = cpu / scenes, summary.episodes / scenes
    stage_s = {}
    for o in summary.outcomes:
        stage_s[o.stage] = stage_s.get(o.stage, 0.0) + o.seconds
    # the stages' CPU split as their wall times split (each ran in one worker with its share of the cores)
    per_pair_share = sum(stage_s.get(s, 0.0) for s in PER_EPISODE_STAGES) / sum(stage_s.values())
    fixed, per_pair = per_scene * (1 - per_pair_share), per_scene * per_pair_share / pairs
    manifest_1k = manifest_cpu / scenes * TARGET_SCENES  # hashing grows with the files, the files with the scenes
    projected = TARGET_SCENES * fixed + TARGET_PAIRS * per_pair + manifest_1k
    rss = {q: sampler.at(q) for q in (scenes // 4, scenes // 2, scenes)}
    return [{
        "scenes": scenes, "workers": WORKERS, "pairs/scene": round(pairs), "all ok": summary.ok,
        "CPU-s/scene": per_scene, "wall s": wall, "load start": load, "load end": os.getloadavg()[0],
        "scenes done (N/4, N/2, N)": "/".join(map(str, rss)),
        "worker RSS MB then": "/".join(f"{r:.0f}" for r, _ in rss.values()),
        "worker peak RSS MB then": "/".join(f"{h:.0f}" for _, h in rss.values()),
        "RSS N vs N/4": rss[scenes][0] / max(rss[scenes // 4][0], 1e-9),
        "workers seen": len(sampler.pids), "manifest CPU-s": manifest_cpu, "manifest files": files,
        "fixed CPU-s/scene": fixed, "CPU-ms/pair": per_pair * 1000,
        f"projected CPU-h ({TARGET_SCENES} scenes, {TARGET_PAIRS:,} pairs)": projected / 3600,
        f"projected wall h ({TARGET_CORES} cores)": projected / TARGET_CORES / 3600,
        "projected manifest CPU-s": manifest_1k,
    }]
