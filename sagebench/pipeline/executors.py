"""Where a run's tasks (a stage of a scene, a collider piece) run: in this process, a local process pool, or
Ray. Outputs never depend on which.

Workers share the machine: a pool of N processes gives each cores // N threads, a Ray task as many threads as
the CPUs it asks for, and idle threads sleep (sagebench.threads)."""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from typing import Any, Protocol, TypeVar

from sagebench import ui
from sagebench.errors import ConfigError
from sagebench.threads import share, thread_env, worker_init

T = TypeVar("T")


class Executor(Protocol):
    capacity: int  # tasks it runs at once: what a run keeps in flight to start the biggest pieces first
    nodes: Counter[str]  # tasks ended per Ray node (its id); empty for the local executors

    def submit(self, fn: Callable[[Any], T], arg: Any, *, cpus: int = 1) -> Any: ...

    def wait_any(self, pending: list[Any]) -> list[tuple[Any, Any]]: ...

    def close(self) -> None: ...


class _Ran:
    """The handle of a task the inline executor ran: one object per task, even for equal results."""

    def __init__(self, result: Any):
        self.result = result


class InlineExecutor:
    """Runs each task when submitted, in this process (one worker: simplest to debug, no pickling)."""

    capacity = 1

    def __init__(self) -> None:
        self.nodes: Counter[str] = Counter()

    def submit(self, fn: Callable[[Any], T], arg: Any, *, cpus: int = 1) -> _Ran:
        return _Ran(fn(arg))

    def wait_any(self, pending: list[_Ran]) -> list[tuple[_Ran, Any]]:
        return [(p, p.result) for p in pending]

    def close(self) -> None:
        pass


class PoolExecutor:
    """A local process pool of `workers` processes, each using its share of the cores."""

    def __init__(self, workers: int):
        import multiprocessing

        # spawn: forking a process that has started numba or MuJoCo threads is not safe
        self.threads = share(workers)
        self._pool = ProcessPoolExecutor(max_workers=workers, mp_context=multiprocessing.get_context("spawn"),
                                         initializer=_pool_worker_init, initargs=(self.threads, ui.worker_settings()))
        self.capacity = workers
        self.nodes: Counter[str] = Counter()

    def submit(self, fn: Callable[[Any], T], arg: Any, *, cpus: int = 1) -> Future:
        return self._pool.submit(fn, arg)

    def wait_any(self, pending: list[Future]) -> list[tuple[Future, Any]]:
        done, _ = wait(pending, return_when=FIRST_COMPLETED)
        return [(f, f.result()) for f in done]

    def close(self) -> None:
        self._pool.shutdown(cancel_futures=True)


def _pool_worker_init(threads: int, settings: ui.Settings) -> None:
    """A pool worker: threads.worker_init, the driver's --quiet and --debug (ui.adopt), and Ctrl-C ends it at once
    and without a traceback of its own (it reaches every process of the terminal's group, and the run reports it
    once: cli's Interrupted). What it was writing is a temporary that the next run removes."""
    import os
    import signal

    ui.adopt(settings)
    worker_init(threads)
    signal.signal(signal.SIGINT, lambda *_: os._exit(130))


class RayExecutor:
    """One Ray task per submitted task, asking for the CPUs it uses (at most the CPUs of the cluster's biggest
    node: Ray would wait for ever for a bigger one); with no address a local Ray starts and stops with the
    run. Worker logs stay on the workers: warnings come back in the outcomes, and each task the node it ran on."""

    def __init__(self, address: str | None):
        try:
            import ray
        except ImportError:
            raise ConfigError("the ray executor needs Ray: pip install 'sagebench[ray]'", field="--executor") from None
        self._ray = ray
        self._started = not ray.is_initialized()
        if self._started:
            ray.init(address=address, include_dashboard=False, log_to_driver=False, configure_logging=False)
        self._remote: Any = None
        self.capacity = max(1, int(ray.cluster_resources().get("CPU", 1)))
        self._biggest = max([int(n["Resources"].get("CPU", 0)) for n in ray.nodes() if n["Alive"]] + [1])
        self.nodes: Counter[str] = Counter()

    def submit(self, fn: Callable[[Any], T], arg: Any, *, cpus: int = 1) -> Any:
        # a worker process started for this many threads (its pools read the environment when they start)
        if self._remote is None:
            self._remote = self._ray.remote(_with_threads)
        cpus = min(cpus, self._biggest)
        env = {"env_vars": thread_env(cpus)}
        return self._remote.options(num_cpus=cpus, runtime_env=env).remote(fn, arg, cpus)

    def wait_any(self, pending: list[Any]) -> list[tuple[Any, Any]]:
        done, _ = self._ray.wait(pending, num_returns=1)
        got = [(ref, *self._ray.get(ref)) for ref in done]
        self.nodes.update(node for _, node, _ in got)
        return [(ref, result) for ref, _, result in got]

    def close(self) -> None:
        if self._started:
            self._ray.shutdown()


def _with_threads(fn: Callable[[Any], T], arg: Any, threads: int) -> tuple[str, T]:
    """A Ray task: (the id of the node it ran on, `fn(arg)` on `threads` threads; a reused worker may have run a
    task of another size)."""
    import ray

    worker_init(threads)
    return ray.get_runtime_context().get_node_id(), fn(arg)


def make_executor(kind: str, workers: int, ray_address: str | None) -> Executor:
    if kind == "ray":
        return RayExecutor(ray_address)
    return InlineExecutor() if workers == 1 else PoolExecutor(workers)
