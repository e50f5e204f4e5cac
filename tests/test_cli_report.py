"""`sagebench report` on the small demo run with two agents: every page is there, every link and image of every
page resolves inside the report (nothing from the network), the same inputs give the same bytes, a report is
written again in place of an earlier one, and a folder it may not write is refused with nothing written.

tests/test_report_browser.py opens the same report in headless Chromium.
"""

from __future__ import annotations

import hashlib
import json
import shutil
from html.parser import HTMLParser
from pathlib import Path
from urllib.parse import unquote, urlsplit

import numpy as np
import pytest

from sagebench.episodes.load import load_episodes

SCENE = "demo_apartment_0"


def walk(run: Path, out: Path, *, bump: bool) -> Path:
    """Predictions that follow each reference path from station to station (every 0.25 m and the corners). With
    `bump`, an agent 0.08 m north of it that touched something (c = 0.5) at its second and third poses of every
    other episode, and left the last episode out."""
    from sagebench.navsim.policies import oracle_targets

    lines = []
    episodes = load_episodes(run)
    for n, e in enumerate(episodes[:-1] if bump else episodes):
        xy = oracle_targets(e.reference_path, 0.25)
        yaw = np.append(np.arctan2(*np.diff(xy, axis=0).T[::-1]), 0.0)
        yaw[0], yaw[-1] = e.start_yaw, yaw[-2] if len(yaw) > 1 else e.start_yaw
        poses = [[float(x), float(y) + (0.08 if bump and k else 0.0), float(e.start[2]), float(a)]
                 for k, ((x, y), a) in enumerate(zip(xy, yaw))]
        c = [0.0] * len(poses)
        if bump and n % 2 == 0:
            c[1:3] = [0.5] * len(c[1:3])
        lines.append(json.dumps({"episode_id": e.episode_id, "poses": poses, "stopped": True,
                                 "collision_intensity": c}))
    out.write_text("\n".join(lines) + "\n")
    return out


@pytest.fixture(scope="module")
def agents(demo_eval_run, tmp_path_factory) -> tuple[Path, Path]:
    d = tmp_path_factory.mktemp("agents")
    return walk(demo_eval_run, d / "oracle.jsonl", bump=False), walk(demo_eval_run, d / "bumpy.jsonl", bump=True)


@pytest.fixture(scope="module")
def report(demo_eval_run, agents, tmp_path_factory) -> Path:
    """The report of the small demo run with both agents (views rendered). Read-only."""
    from sagebench.cli import main

    out = tmp_path_factory.mktemp("report") / "report"
    with pytest.raises(SystemExit) as exc:
        main(["-q", "report", str(demo_eval_run), "--predictions", str(agents[0]), "--predictions", str(agents[1]),
              "--out", str(out)])
    assert exc.value.code in (0, None)
    return out


class Links(HTMLParser):
    """Every href and src of a page (SVG's <image href> too) and the ids it declares."""

    def __init__(self) -> None:
        super().__init__()
        self.refs: list[tuple[str, str]] = []
        self.ids: set[str] = set()

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        for name, value in attrs:
            if name in ("href", "src", "xlink:href") and value is not None:
                self.refs.append((tag, value))
            if name == "id" and value:
                self.ids.add(value)


def links(page: Path) -> Links:
    parser = Links()
    parser.feed(page.read_text(encoding="utf-8"))
    return parser


def hashes(root: Path) -> dict[str, str]:
    return {p.relative_to(root).as_posix(): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(root.rglob("*")) if p.is_file() and p.name != ".sagebench.lock"}


def test_a_page_for_the_run_each_scene_each_episode_and_the_agents(report, demo_eval_run):
    episodes = load_episodes(demo_eval_run)
    pages = sorted(p.relative_to(report).as_posix() for p in report.rglob("*.html"))
    assert pages == sorted(["index.html", "agents.html", f"scenes/{SCENE}.html",
                            *(f"episodes/{e.episode_id}.html" for e in episodes)])
    index = json.loads((report / "report.json").read_text())
    assert [a["agent"] for a in index["predictions"]] == ["oracle", "bumpy"]
    assert index["files"] == sorted(hashes(report).keys() - {"report.json"})
    trajectories = {e.reference_path.tobytes() for e in episodes}
    assert len(list((report / "img" / SCENE).glob("*_start.jpg"))) == len(trajectories) == 8


def test_every_link_and_image_of_every_page_resolves_inside_the_report(report):
    checked = 0
    for page in sorted(report.rglob("*.html")):
        found = links(page)
        for tag, ref in found.refs:
            parts = urlsplit(ref)
            if ref == "data:,":  # the empty favicon: no request for one
                continue
            assert not parts.scheme and not parts.netloc, f"{page.name}: {tag} {ref} leaves the report"
            if not parts.path:
                assert parts.fragment in found.ids, f"{page.name}: {ref}"
                continue
            target = (page.parent / unquote(parts.path)).resolve()
            assert target.is_relative_to(report.resolve()) and target.is_file(), f"{page.name}: {tag} {ref}"
            checked += 1
        assert "http://" not in page.read_text() and "https://" not in page.read_text()
    assert checked > 8 * 3 * 5  # each episode page links its CSS, script, map, two views, scene, overview


def test_an_episode_page_shows_its_instruction_both_paths_contact_and_metrics(report, demo_eval_run, agents):
    e = load_episodes(demo_eval_run)[0]
    text = (report / "episodes" / f"{e.episode_id}.html").read_text()
    import html

    assert f'<blockquote class="instruction" id="instruction">{html.escape(e.instruction)}</blockquote>' in text
    assert text.count('<polyline class="reference"') == 1
    assert text.count('<polyline class="agent" data-agent="oracle"') == 1
    assert text.count('<polyline class="agent" data-agent="bumpy"') == 1
    assert text.count('<path class="contact"') == 2  # bumpy's second and third poses
    assert "bumpy: 2 of" in text and "oracle: 0 of" in text
    last = load_episodes(demo_eval_run)[-1]
    assert "no prediction: every metric at its worst" in (report / "episodes" / f"{last.episode_id}.html").read_text()


def test_the_same_inputs_give_the_same_report(report, demo_eval_run, agents, tmp_path, run_cli):
    again = tmp_path / "again"
    code, _, err = run_cli("-q", "report", demo_eval_run, "--predictions", agents[0], "--predictions", agents[1],
                           "--out", again)
    assert code == 0, err
    assert hashes(again) == hashes(report)


def test_a_report_is_written_again_over_an_earlier_one(report, demo_eval_run, tmp_path, run_cli):
    out = tmp_path / "report"
    shutil.copytree(report, out)
    (out / "my_notes.txt").write_text("the user's")
    code, stdout, err = run_cli("report", demo_eval_run, "--out", out, "--no-views")
    assert code == 0, err
    assert stdout.splitlines()[-1] == f"open {out / 'index.html'} in a browser (no server needed)"
    # the earlier report's views and agents page are gone, the user's file is kept
    assert not (out / "agents.html").exists() and not list(out.rglob("*.jpg"))
    assert (out / "my_notes.txt").read_text() == "the user's"
    assert set(json.loads((out / "report.json").read_text())["files"]) == hashes(out).keys() - {"report.json",
                                                                                                 "my_notes.txt"}


@pytest.mark.parametrize("where, message", [
    ("run/report", "error: --out: {out} lies inside the run {run}: give a folder outside it"),
    ("mine", "error: --out: {out} is not empty and holds no report output; use a new --out"),
    ("new", "error: {pred}:1: episode_id: unknown episode id 'nope': not an episode being evaluated (1 unknown in "
            "all)"),
])
def test_a_folder_it_may_not_write_or_bad_predictions_are_refused_and_nothing_written(
        demo_eval_run, agents, tmp_path, run_cli, where, message):
    run = tmp_path / "run"
    shutil.copytree(demo_eval_run, run)
    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "thesis.tex").write_text("the user's")
    pred = tmp_path / "bad.jsonl"
    pred.write_text(agents[0].read_text().replace(load_episodes(run)[0].episode_id, "nope"))
    out = tmp_path / where
    before = hashes(tmp_path)
    code, stdout, err = run_cli("report", run, "--out", out, "--predictions",
                                pred if where == "new" else agents[0])
    assert (code, stdout) == (2, "") and err == message.format(out=out, run=run, pred=pred) + "\n"
    assert hashes(tmp_path) == before and (where == "mine") == out.exists()


# ------------------------------------------------------------------ in a real browser


@pytest.fixture(scope="module")
def browser():
    from browser import Browser, find_chromium

    if find_chromium() is None:
        pytest.skip("chromium is not installed (Debian: apt-get install chromium; .ci/run installs it where apt "
                    "can): the report's pages were not opened in a browser")
    with Browser() as b:
        yield b


def not_blank(png: bytes) -> bool:
    import cv2

    img = cv2.imdecode(np.frombuffer(png, np.uint8), cv2.IMREAD_COLOR)
    return img.shape[0] >= 600 and float(img.std()) > 20 and len(np.unique(img.reshape(-1, 3), axis=0)) > 100


def test_every_page_opens_in_chromium_with_no_error_and_every_image_drawn(browser, report, tmp_path):
    # the check sees what breaks a page: an image that is not there, a script that fails
    broken = tmp_path / "broken.html"
    broken.write_text('<!DOCTYPE html><img src="missing.png"><script>undefinedFunction();</script>')
    errors = browser.open(broken).errors
    assert len(errors) == 2 and any("missing.png" in e for e in errors) and any("undefinedFunction" in e for e in errors)
    pages = sorted(report.rglob("*.html"))
    for path in pages:
        page = browser.open(path)
        assert page.errors == [], path
        assert page.evaluate("Array.from(document.images).every((i) => i.complete && i.naturalWidth > 0)"), path
        if path.name == "index.html":
            assert not_blank(page.screenshot())
        page.close()
    assert len(pages) == 3 + 24


def test_an_episode_page_in_chromium_shows_the_instruction_both_paths_and_the_metrics(browser, report,
                                                                                     demo_eval_run, agents):
    from sagebench.settings.evaluate import EvaluateConfig
    from sagebench.stages.evaluate import evaluate

    e = load_episodes(demo_eval_run)[0]
    page = browser.open(report / "episodes" / f"{e.episode_id}.html")
    assert not_blank(page.screenshot())
    assert page.evaluate("document.getElementById('instruction').textContent") == e.instruction
    assert page.evaluate("document.querySelectorAll('svg.map polyline.reference').length") == 1
    assert page.evaluate("Array.from(document.querySelectorAll('svg.map polyline.agent'))"
                         ".map((p) => [p.dataset.agent, p.points.length])") == [
        ["oracle", len(json.loads(agents[0].read_text().splitlines()[0])["poses"])],
        ["bumpy", len(json.loads(agents[1].read_text().splitlines()[0])["poses"])]]
    shown = page.evaluate("Array.from(document.querySelectorAll('#metrics tbody tr'))"
                          ".map((r) => Array.from(r.cells).map((c) => c.textContent.trim()))")
    for row, pred in zip(shown, agents):
        score = evaluate(demo_eval_run, pred, EvaluateConfig(allow_missing=True)).scores[0].metrics
        assert row[:5] == [pred.stem, f"{score.sr:.3f}", f"{score.osr:.3f}", f"{score.spl:.3f}", f"{score.ne:.3f}"]
    assert page.evaluate("document.querySelectorAll('svg.map .contact').length") == 2


def test_a_scene_page_filters_its_trajectories_and_the_agents_table_sorts(browser, report, demo_eval_run):
    episodes = load_episodes(demo_eval_run)
    kind = next(e.type for e in episodes if e.level == "high")
    page = browser.open(report / "scenes" / f"{SCENE}.html")
    shown = ("[document.querySelectorAll('svg.map g:not(.off)').length, "
             "document.querySelectorAll('#episodes tbody tr:not(.off)').length]")
    assert page.evaluate(shown) == [8, len(episodes)]
    page.evaluate(f"(() => {{ const s = document.getElementById('type'); s.value = {json.dumps(kind)}; "
                  "s.dispatchEvent(new Event('change')); })()")
    with_kind = {e.reference_path.tobytes() for e in episodes if e.type == kind}
    assert page.evaluate(shown) == [len(with_kind), sum(e.type == kind for e in episodes)] and len(with_kind) < 8
    page = browser.open(report / "agents.html")
    column = "bumpy NE"
    values = ("Array.from(document.querySelectorAll('#episodes tbody tr')).map((r) => parseFloat(r.cells["
              f"Array.from(document.querySelectorAll('#episodes th')).findIndex((h) => h.textContent === '{column}')"
              "].dataset.v))")
    page.evaluate(f"Array.from(document.querySelectorAll('#episodes th')).find((h) => h.textContent === '{column}')"
                  ".click()")
    ascending = page.evaluate(values)
    assert ascending == sorted(ascending) and ascending != sorted(ascending, reverse=True)
