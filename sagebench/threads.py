"""How many cores a process's compute pools use and how their idle threads wait, set once per process.

sagebench's kernels run on numba's OpenMP layer (libgomp). By default libgomp spins an idle worker thread for a
while before it sleeps, so between two parallel regions a waiting thread burns a core that a policy model, a
second env or another worker on the same machine needed: with other work on the cores one env stepped 1.8
steps/s at 0.18-0.27 CPU-s per step, against 5.3-7.1 steps/s and 0.053-0.065 CPU-s with a passive wait
(issue 27). `share_cores` therefore sets, before numba's thread pool starts:

- OMP_WAIT_POLICY (PASSIVE by default: idle threads sleep at once), unless the environment already sets it;
- numba's pool size (NUMBA_NUM_THREADS) and the calling thread's thread count to `threads`;
- OMP_NUM_THREADS, OPENBLAS_NUM_THREADS, MKL_NUM_THREADS (unless set) for the child processes it starts, whose
  BLAS libraries read them when they load (this process's are already loaded with numpy).

Call it at a process's entry point (a command, an env's constructor, a worker's start). It is idempotent: the
first call fixes the wait policy and the pool size; a later call can only lower the calling thread's count,
since libgomp reads its settings once, when numba's pool starts.

Before that, importing sagebench (every command, and a program using the Python API) calls `passive_by_default`:
idle threads sleep and numba's pool has this process's cores, unless the environment says otherwise, in every
process, also one that never reaches a `share_cores` (validate: 5.53 CPU-s spinning against 3.99 passive on a
loaded machine, issue 40). A later first `share_cores` still chooses its own values.
"""

from __future__ import annotations

import os
import sys
import threading
from dataclasses import dataclass
from typing import Literal

WaitPolicy = Literal["passive", "active", "openmp"]  # openmp: leave the OpenMP runtime's own default (spin, then sleep)
_CHILD_THREAD_VARS = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")


@dataclass(frozen=True)
class ThreadSetup:
    """What a process's pools use after `share_cores`."""

    threads: int  # numba threads of the calling thread (and the pool's size when it started after the first call)
    wait_policy: str  # OMP_WAIT_POLICY in effect: PASSIVE, ACTIVE or "default" (the runtime's own)
    pool_started_before: bool  # numba's pool was already running: its size and wait policy could not change


_lock = threading.Lock()
_first: ThreadSetup | None = None
_defaults: dict[str, str] = {}  # what passive_by_default set (not the user): share_cores's first call may replace it


def available_cores() -> int:
    """Cores this process may run on (its CPU affinity), at least 1."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not Linux
        return max(1, os.cpu_count() or 1)


def _pool_started() -> bool:
    """Whether numba's threading layer is running (only then has libgomp read OMP_WAIT_POLICY)."""
    if "numba" not in sys.modules:
        return False
    from numba.np.ufunc import parallel

    return bool(getattr(parallel, "_is_initialized", False))


def passive_by_default() -> None:
    """Idle OpenMP threads sleep and numba's pool has this process's cores (module docstring), for the variables
    the environment leaves unset; nothing once a pool is running or `share_cores` has run."""
    with _lock:
        if _first is not None or _pool_started():
            return
        wanted = {"OMP_WAIT_POLICY": "PASSIVE"}
        if "numba" not in sys.modules:  # numba reads its pool size when it is imported
            wanted["NUMBA_NUM_THREADS"] = str(available_cores())
        for var, value in wanted.items():
            if var not in os.environ:
                os.environ[var] = _defaults[var] = value


def share_cores(threads: int | None = None, *, wait: WaitPolicy = "passive") -> ThreadSetup:
    """Size this process's compute threads to `threads` cores (None: every core it may use) and make idle OpenMP
    threads wait as `wait` says (module docstring); returns what is in effect."""
    global _first
    if threads is not None and threads < 1:
        raise ValueError(f"threads must be at least 1, got {threads}")
    n = min(threads or available_cores(), available_cores())
    with _lock:
        started = _pool_started()
        if _first is None and not started:
            for var, value in _defaults.items():  # the defaults give way to this first call's choice
                if os.environ.get(var) == value:
                    del os.environ[var]
            if wait != "openmp":
                os.environ.setdefault("OMP_WAIT_POLICY", wait.upper())
            os.environ["NUMBA_NUM_THREADS"] = str(n)
            for var in _CHILD_THREAD_VARS:
                os.environ.setdefault(var, str(n))
            if "numba" in sys.modules:  # imported, pool not started: numba read the size at import; set it again
                import numba
                from numba.np.ufunc import parallel

                numba.config.NUMBA_NUM_THREADS = parallel.NUM_THREADS = n
        if "numba" in sys.modules:
            import numba

            n = min(n, numba.config.NUMBA_NUM_THREADS)
            numba.set_num_threads(n)
        setup = ThreadSetup(threads=n, wait_policy=os.environ.get("OMP_WAIT_POLICY", "default"),
                            pool_started_before=started)
        if _first is None:
            _first = setup
        return setup


def share(workers: int, cores: int | None = None) -> int:
    """Threads each of `workers` processes sharing `cores` (default: this process's) gets: cores // workers, >= 1."""
    if workers < 1:
        raise ValueError(f"workers must be >= 1, got {workers}")
    return max(1, (available_cores() if cores is None else cores) // workers)


def thread_env(threads: int) -> dict[str, str]:
    """The environment of a process started to use `threads` threads (a Ray task's runtime env): every pool starts
    that size and idle OpenMP threads sleep."""
    if threads < 1:
        raise ValueError(f"threads must be >= 1, got {threads}")
    return {"OMP_WAIT_POLICY": "PASSIVE", "NUMBA_NUM_THREADS": str(threads),
            **dict.fromkeys(_CHILD_THREAD_VARS, str(threads))}


def worker_init(threads: int) -> None:
    """A worker sharing the machine (a run's pool process, a Ray task): `share_cores(threads)`, and the BLAS pools
    numpy may already have started lowered to `threads` too (they read their variables only when they load). The
    variables are set outright: values inherited from the parent (its own share_cores) are the parent's share."""
    os.environ.update(thread_env(threads))
    share_cores(threads)
    if "numpy" in sys.modules:
        from threadpoolctl import threadpool_limits

        threadpool_limits(threads)
