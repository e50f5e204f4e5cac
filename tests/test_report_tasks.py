"""`sagebench report` over predictions of every task (a small multi-task run on the tiny scene): each task's agents
are summarised by that task's own metrics, and each episode's page shows its task's."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest
from test_episodes_tasks import all_tasks, tiny_built  # noqa: F401 - fixtures

from sagebench.episodes.load import load_episodes
from sagebench.evaluation.scoring import TASK_METRICS
from sagebench.report.pages import LABELS


def _stationary(run: Path, out: Path, tasks: set[str]) -> Path:
    """An agent that stops where it starts on every episode of `tasks` (its contact measured: none)."""
    lines = [json.dumps({"episode_id": e.episode_id, "poses": [[*map(float, e.start), e.start_yaw]] * 2,
                         "stopped": True, "collision_intensity": [0.0, 0.0]})
             for e in load_episodes(run) if e.task in tasks]
    out.write_text("\n".join(lines) + "\n")
    return out


def _text(html: str) -> str:
    return re.sub(r"\s+", " ", re.sub(r"<[^>]+>", " ", html))


@pytest.fixture(scope="module")
def report(all_tasks, tmp_path_factory) -> Path:  # noqa: F811 - the imported fixture
    from sagebench.cli import main

    d = tmp_path_factory.mktemp("report")
    every = _stationary(all_tasks, d / "still.jsonl", set(TASK_METRICS))
    nogoal = _stationary(all_tasks, d / "nogoal_only.jsonl", {"nogoal"})
    with pytest.raises(SystemExit) as done:
        main(["-q", "report", str(all_tasks), "--predictions", str(every), "--predictions", str(nogoal),
              "--out", str(d / "report"), "--no-views"])
    assert done.value.code in (0, None)
    return d / "report"


def test_the_overview_summarises_each_task_by_its_own_metrics(report):
    index = (report / "index.html").read_text()
    for task, names in TASK_METRICS.items():
        table = re.search(rf'<h3>task {task}</h3>\s*<table class="sortable" id="agents-{task}">(.*?)</table>',
                          index, flags=re.S)
        assert table, task
        head = re.findall(r"<th>(.*?)</th>", table.group(1))
        assert head[4:] == [LABELS[m] for m in names]
    def summary(task: str) -> str:
        return _text(index.split(f'id="agents-{task}"')[1].split("</table>")[0])

    # agent, file, episodes, without prediction, SR: nogoal_only's other episodes count as missing
    assert "still still.jsonl 6 0 0.000" in summary("nogoal")
    assert "nogoal_only nogoal_only.jsonl 6 0 0.000" in summary("nogoal")
    assert "nogoal_only nogoal_only.jsonl 6 6 0.000" in summary("pointnav")


def test_an_episode_page_shows_its_tasks_metrics(report, all_tasks):  # noqa: F811
    for e in load_episodes(all_tasks):
        if e.task not in ("nogoal", "pointnav"):
            continue
        page = (report / "episodes" / f"{e.episode_id}.html").read_text()
        metrics = page.split('id="metrics"')[1].split("</table>")[0]
        assert re.findall(r"<th>(.*?)</th>", metrics)[1:-3] == [LABELS[m] for m in TASK_METRICS[e.task]]
        assert ("no prediction" in metrics) == (e.task != "nogoal")  # nogoal_only has none for pointnav
