"""`sagebench run --executor ray --ray-address` on a real two-node Ray cluster (docs/run.md, "On a Ray cluster"):
a head and a second node started as separate `ray start` processes on this machine, with token authentication,
one CPU each and distinct custom resources, the scenes, `out` and the cache on storage both see. The run must
spread over both nodes and write what the local executor writes, byte for byte."""

from __future__ import annotations

import json
import os
import re
import secrets
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest

from sagebench.pipeline.manifest import hash_run
from test_pipeline_run import CONFIG, SCENES, _add_planter, _walled_tiny_scene

pytest.importorskip("ray")
pytestmark = [pytest.mark.slow, pytest.mark.ray_cluster]

RAY = Path(sys.executable).with_name("ray")
SAGEBENCH = Path(sys.executable).with_name("sagebench")


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _ours(temp_dir: Path) -> list[int]:
    """Pids of the processes of this cluster: every Ray process names its temp dir on its command line."""
    mark = str(temp_dir).encode()
    pids = []
    for entry in Path("/proc").iterdir():
        try:
            if entry.name.isdigit() and mark in (entry / "cmdline").read_bytes():
                pids.append(int(entry.name))
        except OSError:
            continue
    return pids


def _stop(nodes: list[subprocess.Popen], temp_dir: Path) -> None:
    """Stop this cluster alone (`ray stop` would stop every Ray of the machine's user): each `ray start --block`
    and its session, then any process left that names the temp dir; TERM, then KILL after a grace period."""
    for sig in (signal.SIGTERM, signal.SIGKILL):
        for node in nodes:
            try:
                os.killpg(node.pid, sig)
            except ProcessLookupError:
                pass
        for pid in _ours(temp_dir):
            try:
                os.kill(pid, sig)
            except ProcessLookupError:
                pass
        deadline = time.monotonic() + 20
        while (any(n.poll() is None for n in nodes) or _ours(temp_dir)) and time.monotonic() < deadline:
            time.sleep(0.5)
    for node in nodes:
        node.wait(timeout=10)


def _wait_for_nodes(env: dict, address: str, count: int, log: Path) -> None:
    probe = ("import ray, sys; ray.init(address=sys.argv[1], configure_logging=False); "
             "print(sum(n['Alive'] for n in ray.nodes()))")
    deadline = time.monotonic() + 180
    while time.monotonic() < deadline:
        got = subprocess.run([sys.executable, "-c", probe, address], env=env, capture_output=True, text=True)
        if got.stdout.strip() == str(count):
            return
        time.sleep(2)
    pytest.fail(f"the cluster did not reach {count} nodes: {got.stdout} {got.stderr}\n{log.read_text()}")


@contextmanager
def cluster(root: Path) -> Iterator[tuple[str, dict]]:
    """(HEAD:PORT, the environment every node and the driver share: the token) of a head and a second node."""
    # Ray's temp dir holds its sockets, whose paths may not pass 107 bytes: a short one, not under tmp_path
    temp_dir, port = Path(tempfile.mkdtemp(prefix="sbray-")), _free_port()
    address = f"127.0.0.1:{port}"
    env = os.environ | {"RAY_AUTH_MODE": "token", "RAY_AUTH_TOKEN": secrets.token_hex(16),
                        "RAY_USAGE_STATS_ENABLED": "0"}
    common = ["--block", "--node-ip-address", "127.0.0.1", "--num-cpus", "1", "--temp-dir", str(temp_dir),
              "--disable-usage-stats"]
    log = root / "ray-start.log"
    nodes: list[subprocess.Popen] = []
    try:
        with log.open("w") as out:
            for args in (["--head", "--port", str(port), "--include-dashboard", "false",
                          "--resources", '{"head": 1}'], ["--address", address, "--resources", '{"node2": 1}']):
                nodes.append(subprocess.Popen([RAY, "start", *args, *common], env=env, stdout=out,
                                              stderr=subprocess.STDOUT, start_new_session=True))
                _wait_for_nodes(env, address, len(nodes), log)
        yield address, env
    finally:
        _stop(nodes, temp_dir)
        shutil.rmtree(temp_dir, ignore_errors=True)


def test_a_two_node_cluster_writes_what_the_local_executor_writes(tmp_path, run_cli):
    """Two scenes (each with a concave collider piece) on a head and a second node, one CPU each: the run asks
    for at most one CPU a task (validate's default 2 would never be placed), reports tasks on both nodes, and
    its manifest and every output equal a local run's, byte for byte."""
    for (name, width), sid in zip((("a", 0.6), ("b", 0.7)), SCENES):
        _walled_tiny_scene(tmp_path / "scenes" / name, sid)
        _add_planter(tmp_path / "scenes" / name, width)
    for name in ("local", "cluster"):
        (tmp_path / f"{name}.toml").write_text(CONFIG.format(out=name))
    code, out, err = run_cli("-q", "run", tmp_path / "local.toml")
    assert code == 0, out + err
    with cluster(tmp_path) as (address, env):
        done = subprocess.run([SAGEBENCH, "-q", "run", tmp_path / "cluster.toml", "--executor", "ray",
                               "--ray-address", address], env=env, capture_output=True, text=True, timeout=900)
    assert done.returncode == 0, done.stdout + done.stderr
    nodes = re.search(r"ray nodes\s+(\d+)\s+tasks per node: (\w+) (\d+), (\w+) (\d+)", done.stdout)
    assert nodes and nodes[1] == "2" and nodes[2] != nodes[4], done.stdout
    assert int(nodes[3]) + int(nodes[5]) == 2 * (4 + 1 + 1)  # per scene: 4 stages, its export's plan, a piece
    local, remote = tmp_path / "local", tmp_path / "cluster"
    assert (remote / "manifest.json").read_bytes() == (local / "manifest.json").read_bytes()
    assert hash_run(remote) == hash_run(local) == json.loads((local / "manifest.json").read_text())["files"]
