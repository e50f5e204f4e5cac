"""Where scene-stage tasks run: in this process, a local process pool, or Ray. Outputs never depend on which."""

from __future__ import annotations

from collections.abc import Callable
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from typing import Any, Protocol

from sagebench.errors import ConfigError
from sagebench.pipeline.stages import STAGES, Outcome, Task, run_task


class Executor(Protocol):
    def submit(self, task: Task) -> Any: ...

    def wait_any(self, pending: list[Any]) -> list[tuple[Any, Outcome]]: ...

    def close(self) -> None: ...


class InlineExecutor:
    """Runs each task when submitted, in this process (one worker: simplest to debug, no pickling)."""

    def submit(self, task: Task) -> Outcome:
        return run_task(task)

    def wait_any(self, pending: list[Outcome]) -> list[tuple[Outcome, Outcome]]:
        return [(p, p) for p in pending]

    def close(self) -> None:
        pass


class PoolExecutor:
    """A local process pool of `workers` processes."""

    def __init__(self, workers: int):
        import multiprocessing

        # spawn: forking a process that has started numba or MuJoCo threads is not safe
        self._pool = ProcessPoolExecutor(max_workers=workers, mp_context=multiprocessing.get_context("spawn"))

    def submit(self, task: Task) -> Future:
        return self._pool.submit(run_task, task)

    def wait_any(self, pending: list[Future]) -> list[tuple[Future, Outcome]]:
        done, _ = wait(pending, return_when=FIRST_COMPLETED)
        return [(f, f.result()) for f in done]

    def close(self) -> None:
        self._pool.shutdown(cancel_futures=True)


class RayExecutor:
    """One Ray task per scene and stage, asking for the CPUs the stage uses; with no address a local Ray
    starts and stops with the run. Worker logs stay on the workers: warnings come back in the outcomes."""

    def __init__(self, address: str | None):
        try:
            import ray
        except ImportError:
            raise ConfigError("the ray executor needs Ray: pip install 'sagebench[ray]'", field="--executor") from None
        self._ray = ray
        self._started = not ray.is_initialized()
        if self._started:
            ray.init(address=address, include_dashboard=False, log_to_driver=False, configure_logging=False)
        self._remote: Callable = ray.remote(run_task)

    def submit(self, task: Task) -> Any:
        return self._remote.options(num_cpus=STAGES[task.stage].cpus(task)).remote(task)

    def wait_any(self, pending: list[Any]) -> list[tuple[Any, Outcome]]:
        done, _ = self._ray.wait(pending, num_returns=1)
        return [(ref, self._ray.get(ref)) for ref in done]

    def close(self) -> None:
        if self._started:
            self._ray.shutdown()


def make_executor(kind: str, workers: int, ray_address: str | None) -> Executor:
    if kind == "ray":
        return RayExecutor(ray_address)
    return InlineExecutor() if workers == 1 else PoolExecutor(workers)
