"""RunScheduler: the run's collider pieces as one pool (biggest first, at most `capacity` in flight, a shared
piece once), each scene's export after its plan and its pieces; checked with an executor that runs nothing."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from sagebench.collider_export.pieces import Piece
from sagebench.pipeline.pieces import PieceOutcome, PieceTask
from sagebench.pipeline.schedule import RunScheduler
from sagebench.pipeline.tasks import STAGES, Outcome


def _piece(sid: str, key: str, faces: int) -> PieceTask:
    return PieceTask(sid, key, Piece(key, np.zeros((3, 3)), np.zeros((faces, 3), np.int64), ("hull",)), 0.0, {})


class FakeExecutor:
    """Records what is submitted; ends the oldest pending task first; plans come from PLANS."""

    def __init__(self, plans: dict[str, tuple[PieceTask, ...]], capacity: int):
        self.plans, self.capacity = plans, capacity
        self.log: list[tuple[str, str]] = []  # (function, scene id / piece key)
        self.in_flight: list[str] = []  # piece keys
        self.most_in_flight = 0

    def submit(self, fn, arg, *, cpus=1):
        if fn.__name__ == "run_piece":
            self.in_flight.append(arg.key)
            self.most_in_flight = max(self.most_in_flight, len(self.in_flight))
            self.log.append(("piece", arg.key))
        else:
            self.log.append((arg.stage if fn.__name__ == "run_task" else "plan", arg.scene_id))
        return [fn.__name__, arg]

    def wait_any(self, pending):
        handle = pending[0]
        name, arg = handle
        if name == "run_piece":
            self.in_flight.remove(arg.key)
            return [(handle, PieceOutcome(arg.key, arg.piece.name, "hull", 0.0, "here:1"))]
        if name == "plan_export":
            return [(handle, self.plans[arg.scene_id])]
        return [(handle, Outcome(arg.stage, arg.scene_id, "ran", 0.0))]

    def close(self):
        pass


def _run(plans, capacity=1):
    executor = FakeExecutor(plans, capacity)
    scheduler = RunScheduler(executor, {sid: Path(sid) for sid in plans}, Path("run"), dict.fromkeys(STAGES, {}), None)
    outcomes = list(scheduler.outcomes())
    return executor, scheduler, outcomes


def test_pieces_of_all_scenes_go_biggest_first_and_each_export_waits_for_its_own():
    plans = {"a": (_piece("a", "a1", 10), _piece("a", "a2", 500)), "b": (_piece("b", "b1", 100),), "c": ()}
    executor, scheduler, outcomes = _run(plans, capacity=1)
    assert len(outcomes) == 3 * len(STAGES) and all(o.status == "ran" for o in outcomes)
    pieces = [key for kind, key in executor.log if kind == "piece"]
    # a's plan ends first, so its big piece starts alone; b's 100 faces then go before a's 10
    assert pieces == ["a2", "b1", "a1"] and executor.most_in_flight == 1
    at = {entry: i for i, entry in enumerate(executor.log)}
    assert at[("export_usd", "a")] > max(at[("piece", "a1")], at[("piece", "a2")])
    assert at[("export_usd", "b")] > at[("piece", "b1")]
    assert at[("export_usd", "c")] > at[("plan", "c")]
    assert sorted(p.key for p in scheduler.pieces) == ["a1", "a2", "b1"]


def test_a_piece_shared_by_two_scenes_runs_once_and_capacity_bounds_what_is_in_flight():
    shared = 300
    plans = {"a": (_piece("a", "s", shared), _piece("a", "a1", 20), _piece("a", "a2", 30)),
             "b": (_piece("b", "s", shared), _piece("b", "b1", 40))}
    executor, scheduler, _ = _run(plans, capacity=2)
    pieces = [key for kind, key in executor.log if kind == "piece"]
    assert sorted(pieces) == ["a1", "a2", "b1", "s"] and executor.most_in_flight == 2
    at = {entry: i for i, entry in enumerate(executor.log)}
    assert at[("export_usd", "b")] > at[("piece", "s")] and at[("export_usd", "a")] > at[("piece", "s")]
