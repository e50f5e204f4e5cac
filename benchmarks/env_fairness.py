"""Rows of `python -m benchmarks env` on sharing the machine with a policy: OpenMP's default wait against a passive
one under a competing load, and a policy over HTTP (each request encoding) against the same policy in-process.

Wait policy: each rollout runs in a fresh process (libgomp reads its wait policy once, when numba's pool starts)
while two busy processes compete for the cores; the two policies alternate ROUNDS times and medians are taken.
HTTP: the policy server is a separate process that decodes every request (its CPU counted apart), answering the
same step-driven actions as the in-process policy; the four transports alternate ROUNDS times.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from sagebench.navsim.actions import Action
from sagebench.navsim.http_policy import HttpPolicy
from sagebench.navsim.rollout import rollout
from sagebench.navsim.simulator import Simulator
from sagebench.settings.rollout import EnvConfig

ROUNDS = 3
STEPS = 20  # actions per episode
EPISODES = 2  # per rollout (stepped one at a time for the wait policy, together over HTTP)
COMPETITORS = 2  # busy processes beside the measured rollout: the cores' other tenants
_SPIN = "import os\nparent = os.getppid()\nwhile os.getppid() == parent:\n    pass\n"  # ends with its parent
_CLEAN_ENV = {k: v for k, v in os.environ.items() if k not in ("OMP_WAIT_POLICY", "NUMBA_NUM_THREADS",
                                                                 "OMP_NUM_THREADS")}

_ROLLOUT_CHILD = """
import json, sys, time
from sagebench.threads import share_cores
share_cores(2, wait=sys.argv[2])
from sagebench.navsim.policies import RandomWalk
from sagebench.navsim.rollout import rollout
from sagebench.navsim.simulator import EnvConfig, Simulator
sim = Simulator(sys.argv[1], EnvConfig(observations=("rgb", "depth"), max_steps=int(sys.argv[3])), threads=2)
ids = sim.order[:int(sys.argv[4])]
sim.start(ids[:1])
start, cpu = time.perf_counter(), time.process_time()
r = rollout(sim, RandomWalk(seed=0), ids, batch=1, sheet=0)
print(json.dumps([r.steps / (time.perf_counter() - start), (time.process_time() - cpu) / r.steps]))
"""

_SERVER = """
import json, os, sys, threading, time
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from sagebench.navsim.protocol import decode_request

class Handler(BaseHTTPRequestHandler):
    requests = bytes_in = 0
    def do_POST(self):
        body = self.rfile.read(int(self.headers["Content-Length"]))
        fields, images = decode_request(self.headers["Content-Type"], body)
        Handler.requests += 1
        Handler.bytes_in += len(body)
        self._reply({"action": action(fields["step"])})
    def do_GET(self):
        self._reply({"cpu": time.process_time(), "requests": Handler.requests, "bytes": Handler.bytes_in})
    def _reply(self, obj):
        data = json.dumps(obj).encode()
        self.send_response(200)
        self.send_header("Content-Type", "application/json")
        self.send_header("Content-Length", str(len(data)))
        self.end_headers()
        self.wfile.write(data)
    def log_message(self, *args):
        pass

def action(step):
    return "STOP" if step >= int(sys.argv[1]) - 1 else "TURN_LEFT" if step % 5 == 4 else "MOVE_FORWARD"

def orphaned(parent):  # the bench was killed: end with it
    while os.getppid() == parent:
        time.sleep(1)
    os._exit(0)

threading.Thread(target=orphaned, args=(os.getppid(),), daemon=True).start()
server = ThreadingHTTPServer(("127.0.0.1", 0), Handler)
print(server.server_address[1], flush=True)
server.serve_forever()
"""


def _action(step: int) -> Action:
    """The server's rule, in-process."""
    if step >= STEPS - 1:
        return Action.STOP
    return Action.TURN_LEFT if step % 5 == 4 else Action.MOVE_FORWARD


class StepPolicy:
    """The policy server's actions without the server (a rollout's reference)."""

    def begin(self, episodes) -> None:
        pass

    def act(self, slots, observations, infos) -> list:
        return [_action(info["steps"]) for info in infos]


def _competing_load() -> list[subprocess.Popen]:
    return [subprocess.Popen([sys.executable, "-c", _SPIN]) for _ in range(COMPETITORS)]


def _wait_run(run_dir: Path, wait: str) -> tuple[float, float]:
    done = subprocess.run([sys.executable, "-c", _ROLLOUT_CHILD, str(run_dir), wait, str(STEPS), str(EPISODES)],
                          capture_output=True, text=True, check=True, env=_CLEAN_ENV)
    return tuple(json.loads(done.stdout.strip().splitlines()[-1]))


def wait_rows(run_dir: Path) -> list[dict]:
    """One env stepping EPISODES episodes x STEPS actions (224x224 RGB + depth, 2 threads) in a fresh process with
    OpenMP's default wait and with a passive one, alternating, while COMPETITORS busy processes run."""
    load_start = os.getloadavg()[0]
    competitors = _competing_load()
    try:
        rounds = [(_wait_run(run_dir, "openmp"), _wait_run(run_dir, "passive")) for _ in range(ROUNDS)]
    finally:
        for p in competitors:
            p.kill()
            p.wait()
    (spin, spin_cpu), (passive, passive_cpu) = (np.median([r[k] for r in rounds], axis=0) for k in (0, 1))
    load = f"load average {load_start:.1f} before the competitors, {os.getloadavg()[0]:.1f} at the end"
    every = "; ".join(f"{a[0]:.1f}/{b[0]:.1f}" for a, b in rounds)
    return [
        {"name": f"env step, OpenMP default wait, {COMPETITORS} busy processes beside it", "reference": "-",
         "seconds": 1.0 / spin, "speed-up": 1.0, "cpu-s": spin_cpu,
         "notes": f"{spin:.1f} steps/s, median of {ROUNDS} fresh processes; {load}"},
        {"name": "env step, passive wait (the default now), same load", "reference": "OpenMP default wait",
         "seconds": 1.0 / passive, "speed-up": passive / spin, "cpu-s": passive_cpu,
         "notes": f"{passive:.1f} steps/s; default/passive steps/s per round: {every}"},
    ]


def _server(steps: int) -> tuple[subprocess.Popen, str]:
    proc = subprocess.Popen([sys.executable, "-c", _SERVER, str(steps)], stdout=subprocess.PIPE, text=True,
                            env=_CLEAN_ENV)
    return proc, f"http://127.0.0.1:{proc.stdout.readline().strip()}/act"


def _server_stats(url: str) -> dict:
    import urllib.request

    with urllib.request.urlopen(url, timeout=30) as resp:
        return json.loads(resp.read())


def _transport_run(sim: Simulator, ids: list[str], encoding: str | None, url: str) -> tuple[float, float, float, float]:
    """(steps/s, client CPU-s per step, server CPU-s per step, request bytes per step)."""
    before = _server_stats(url) if encoding else None
    policy = HttpPolicy(url, encoding=encoding, workers=2) if encoding else StepPolicy()
    start, cpu = time.perf_counter(), time.process_time()
    r = rollout(sim, policy, ids, batch=len(ids), sheet=0)
    wall, client = time.perf_counter() - start, time.process_time() - cpu
    if not encoding:
        return r.steps / wall, client / r.steps, 0.0, 0.0
    policy.close()
    after = _server_stats(url)
    return (r.steps / wall, client / r.steps, (after["cpu"] - before["cpu"]) / r.steps,
            (after["bytes"] - before["bytes"]) / (after["requests"] - before["requests"]))


def transport_rows(run_dir: Path) -> list[dict]:
    """EPISODES episodes x STEPS actions stepped together (224x224 RGB + depth), the policy in-process or over HTTP
    in each encoding, alternating ROUNDS times."""
    load_start = os.getloadavg()[0]
    proc, url = _server(STEPS)
    try:
        sim = Simulator(run_dir, EnvConfig(observations=("rgb", "depth"), max_steps=STEPS), threads=2)
        ids = sim.order[:EPISODES]
        sim.start(ids)
        kinds = (None, "raw", "png", "json")
        rounds = [{k: _transport_run(sim, ids, k, url) for k in kinds} for _ in range(ROUNDS)]
    finally:
        proc.kill()
        proc.wait()
    med = {k: np.median([r[k] for r in rounds], axis=0) for k in kinds}
    base = med[None][0]
    rows = [{"name": f"rollout, policy in-process ({EPISODES} episodes together)", "reference": "-", "seconds": 1.0 / base,
             "speed-up": 1.0, "cpu-s": med[None][1],
             "notes": f"{base:.1f} steps/s; load average {load_start:.1f} at the start, "
                      f"{os.getloadavg()[0]:.1f} at the end"}]
    label = {"raw": "raw arrays (default)", "png": "PNG RGB + raw depth", "json": "JSON + base64 PNG/.npy (before)"}
    for k in kinds[1:]:
        sps, client, server, size = med[k]
        rows.append({"name": f"rollout over HTTP, {label[k]}", "reference": "policy in-process", "seconds": 1.0 / sps,
                     "speed-up": sps / base, "cpu-s": client,
                     "notes": f"{sps:.1f} steps/s; server {server:.4f} CPU-s/step decoding; {size / 1e3:.0f} kB "
                              f"per request; median of {ROUNDS}, alternating"})
    return rows
