"""A rollout into a predictions file that survives its policy and its process: the episodes asked for run with each
finished one appended as it ends (journal.py), episodes the policy fails set aside, and the record beside the file
(sagebench.evaluation.record) saying what was asked, what the agent observed and what is left; resuming runs
exactly the asked episodes without a line, so the file ends as an uninterrupted rollout's.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

from sagebench.evaluation.predictions import Prediction
from sagebench.evaluation.record import PolicyFailed, RolloutRecord, write_record
from sagebench.navsim.journal import Journal
from sagebench.navsim.policies import Policy
from sagebench.navsim.rollout import RolloutResult, rollout
from sagebench.navsim.simulator import Simulator


@dataclass(frozen=True)
class Written:
    result: RolloutResult  # this run's: steps, failures, the sheet episodes' views
    predictions: list[Prediction]  # every asked episode's that has a line in the file now, in asked order
    complete: bool  # every asked episode has one


def run_into(out: Path, sim: Simulator, policy: Policy, record: RolloutRecord, *, resume: bool, batch: int,
             sheet: Sequence[str], max_failures: int | None, on_step: Callable[[int, int], None] | None = None
             ) -> Written:
    """Run `record.episodes` (with `resume`, those without a line in `out`) into `out` and write the record;
    the views of the `sheet` episodes are kept when this run runs them all. `on_step(asked episodes done,
    steps)` after every step."""
    asked = record.episodes
    journal = Journal.resume(out, asked) if resume else Journal(out, {})
    todo = [i for i in asked if i not in journal.lines]
    write_record(out, record)
    earlier = len(asked) - len(todo)
    try:
        result = rollout(sim, policy, todo, batch=batch, sheet=sheet if set(sheet) <= set(todo) else [],
                         on_step=(lambda done, steps: on_step(earlier + done, steps)) if on_step else None,
                         on_finish=journal.append, max_failures=max_failures)
    finally:
        journal.close()
    complete = all(i in journal.lines for i in asked)
    if complete:
        journal.finish(asked)
    failed = [PolicyFailed(episode_id=i, reason=why) for i, why in result.failed]
    write_record(out, record.model_copy(update={"failed_by_policy": failed, "complete": complete}))
    done = [Prediction.model_validate_json(journal.lines[i]) for i in asked if i in journal.lines]
    return Written(result=result, predictions=done, complete=complete)
