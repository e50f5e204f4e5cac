"""sagebench.threads: each case runs in a fresh interpreter (a process's OpenMP runtime reads its settings once),
and libgomp's own report (OMP_DISPLAY_ENV=VERBOSE) says how numba's pool waits: GOMP_SPINCOUNT 0 is passive
(idle threads sleep at once), 300000 the runtime's default spin before sleeping.

Workers share the machine: each process of a run's pool, and each Ray task, runs its native pools on its share
of the cores, with idle OpenMP threads asleep."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap

import pytest

from sagebench.threads import available_cores, share, share_cores, thread_env

PASSIVE, DEFAULT_SPIN = "GOMP_SPINCOUNT = '0'", "GOMP_SPINCOUNT = '300000'"
KERNEL = """
import numba, numpy as np
@numba.njit(parallel=True, cache=False)
def total(a):
    s = 0.0
    for i in numba.prange(len(a)):
        s += a[i]
    return s
assert total(np.ones(100)) == 100.0
"""


def run_python(*code: str, **env: str) -> tuple[str, str]:
    """(stdout, stderr) of the `code` pieces (each dedented) in a fresh interpreter whose environment lacks the variables share_cores sets,
    plus `env`; libgomp reports its settings on stderr."""
    base = {k: v for k, v in os.environ.items()
            if k not in ("OMP_WAIT_POLICY", "OMP_NUM_THREADS", "NUMBA_NUM_THREADS", "OPENBLAS_NUM_THREADS",
                         "MKL_NUM_THREADS")}
    done = subprocess.run([sys.executable, "-c", "\n".join(textwrap.dedent(c) for c in code)], capture_output=True, text=True, timeout=300,
                          env={**base, "OMP_DISPLAY_ENV": "VERBOSE", **env})
    assert done.returncode == 0, done.stderr
    return done.stdout, done.stderr


def test_the_pool_started_after_share_cores_waits_passively_on_the_cores_given():
    out, err = run_python("""
        import os, numba
        from sagebench.threads import share_cores
        setup = share_cores(1)
    """, KERNEL, """
        print(setup.threads, setup.wait_policy, setup.pool_started_before, numba.get_num_threads(),
              numba.config.NUMBA_NUM_THREADS, os.environ["OPENBLAS_NUM_THREADS"])
    """)
    assert out.split() == ["1", "PASSIVE", "False", "1", "1", "1"]
    assert PASSIVE in err


def test_numba_imported_first_is_sized_before_its_pool_starts():
    out, _ = run_python("""
        import numba
        from sagebench.threads import share_cores
        share_cores(1)
    """, KERNEL, """
        print(numba.config.NUMBA_NUM_THREADS, numba.get_num_threads())
    """)
    assert out.split() == ["1", "1"]


def test_the_users_wait_policy_wins_and_openmp_leaves_the_runtimes_default():
    _, err = run_python("from sagebench.threads import share_cores\nshare_cores(1)\n", KERNEL,
                        OMP_WAIT_POLICY="ACTIVE")
    assert "OMP_WAIT_POLICY = 'ACTIVE'" in err and PASSIVE not in err
    out, err = run_python("import os\nfrom sagebench.threads import share_cores\nprint(share_cores(1, wait='openmp')"
                          ".wait_policy, 'OMP_WAIT_POLICY' in os.environ)\n", KERNEL)
    assert out.split() == ["default", "False"] and DEFAULT_SPIN in err


def test_a_later_call_only_lowers_the_calling_threads_count():
    out, _ = run_python("""
        import numba
        from sagebench.threads import share_cores
    """, KERNEL, """
        before = numba.config.NUMBA_NUM_THREADS
        setup = share_cores(1)
        again = share_cores(1)
        print(setup.pool_started_before, numba.get_num_threads(), numba.config.NUMBA_NUM_THREADS == before,
              again == setup)
    """)
    assert out.split() == ["True", "1", "True", "True"]


def test_threads_are_capped_at_the_cores_this_process_may_use():
    out, _ = run_python(f"from sagebench.threads import share_cores\nprint(share_cores({available_cores() + 7})"
                        ".threads)")
    assert int(out) == available_cores()


def test_zero_threads_is_refused():
    with pytest.raises(ValueError, match="threads must be at least 1, got 0"):
        share_cores(0)


def test_an_env_process_and_rollout_share_cores_by_default(demo_eval_run, tmp_path):
    out, err = run_python(f"""
        import os, numba
        from sagebench.env import NavEnv
        NavEnv({str(demo_eval_run)!r}, {{"observations": [], "max_steps": 2}}, threads=1).reset(seed=0)
        print(os.environ["OMP_WAIT_POLICY"], numba.get_num_threads())
    """)
    assert out.split() == ["PASSIVE", "1"] and PASSIVE in err
    out, err = run_python(f"""
        import os, numba
        from sagebench.cli import main
        try:
            main(["rollout", "--run", {str(demo_eval_run)!r}, "--out", {str(tmp_path / "p.jsonl")!r}, "--policy",
                  "straight", "--obs", "rgb", "--width", "8", "--height", "8", "--episodes", "1", "--threads", "1",
                  "--max-steps", "2", "--quiet"])
        except SystemExit as done:
            assert not done.code, done.code
        print(os.environ["OMP_WAIT_POLICY"], numba.get_num_threads())
    """)
    assert out.split()[-2:] == ["PASSIVE", "1"] and PASSIVE in err


@pytest.mark.parametrize(("workers", "cores", "threads"), [(1, 16, 16), (2, 16, 8), (3, 16, 5), (16, 16, 1),
                                                            (4, 2, 1), (2, 2, 1), (1, 2, 2)])
def test_each_worker_gets_its_share_of_the_cores(workers, cores, threads):
    assert share(workers, cores) == threads


def test_thread_env_sets_every_pool_and_passive_wait():
    env = thread_env(3)
    assert {env[k] for k in ("NUMBA_NUM_THREADS", "OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")} == {"3"}
    assert env["OMP_WAIT_POLICY"] == "PASSIVE"


def pools(_: object) -> dict:
    """What a worker's native pools use (run in the worker)."""
    import numba
    import numpy as np
    from threadpoolctl import threadpool_info

    @numba.njit(parallel=True)
    def total(a):
        s = 0.0
        for i in numba.prange(len(a)):
            s += a[i]
        return s

    total(np.ones(64))
    return {"numba_pool": numba.config.NUMBA_NUM_THREADS, "numba": numba.get_num_threads(),
            "blas": max([p["num_threads"] for p in threadpool_info()] or [0]),
            "wait": os.environ.get("OMP_WAIT_POLICY"), "pid": os.getpid()}


def test_pool_workers_take_their_share():
    from sagebench.pipeline.executors import PoolExecutor

    pool = PoolExecutor(2)
    try:
        (_, got), = pool.wait_any([pool.submit(pools, None)])
    finally:
        pool.close()
    want = share(2)
    assert got["pid"] != os.getpid()
    assert (got["numba_pool"], got["numba"], got["blas"], got["wait"]) == (want, want, want, "PASSIVE")


def test_ray_tasks_use_the_cpus_they_ask_for():
    pytest.importorskip("ray")
    import sys

    from ray import cloudpickle

    from sagebench.pipeline.executors import RayExecutor

    cloudpickle.register_pickle_by_value(sys.modules[__name__])  # Ray's workers cannot import the tests

    ray = RayExecutor(None)
    try:
        (_, got), = ray.wait_any([ray.submit(pools, None, cpus=1)])
    finally:
        ray.close()
    assert (got["numba_pool"], got["numba"], got["blas"], got["wait"]) == (1, 1, 1, "PASSIVE")
