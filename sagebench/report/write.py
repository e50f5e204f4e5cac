"""`sagebench report RUN [--predictions P ...] --out DIR`: the run (and the agents' predictions) as static pages.

Everything is read and drawn before the first file is written. DIR/REPORT_INDEX, written first, says what the
report shows and lists its files: it marks DIR as an earlier report (run_folder.claim_export_dir), and the files
an earlier report listed that this one does not are removed, so DIR always shows one report. Same inputs, same
bytes.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from sagebench import ui
from sagebench.fileio import listed_files, remove_unlisted, write_bytes, write_json
from sagebench.report import pages
from sagebench.report.agents import Agent, score_agents
from sagebench.report.html import CSS, CSS_FILE, JS, JS_FILE
from sagebench.report.run_facts import RunFacts, SceneFacts, read_run
from sagebench.report.svg import map_frame
from sagebench.report.views import render_thumbnails, start_and_goal
from sagebench.settings.render import RenderConfig
from sagebench.settings.report import ReportConfig

REPORT_INDEX = "report.json"
THUMBNAIL = (160, 120)  # the start and goal views, px


@dataclass(frozen=True)
class Report:
    out_dir: Path
    files: dict[str, int]  # relative name -> bytes
    scenes: int
    episodes: int
    agents: list[str]

    def lines(self) -> list[str]:
        pages_n = sum(n.endswith(".html") for n in self.files)
        size = sum(self.files.values())
        agents = f" and {len(self.agents)} agent(s) ({', '.join(self.agents)})" if self.agents else ""
        return [f"report: {self.scenes} scene(s), {self.episodes} episodes{agents}: {pages_n} pages, "
                f"{len(self.files) - pages_n} other files, {size / 2**20:.1f} MiB -> {self.out_dir}",
                f"open {self.out_dir / 'index.html'} in a browser (no server needed)"]


def write_report(run_dir: Path, predictions: Sequence[Path], out_dir: Path, config: ReportConfig = ReportConfig(),
                 *, scene_id: str | None = None) -> Report:
    """Read the run and score the predictions, draw every page, then write them into `out_dir`."""
    run = read_run(run_dir, scene_id)
    agents = score_agents(run_dir, predictions, scene_id)
    files = report_files(run, agents, config)
    out_dir = Path(out_dir)
    earlier = listed_files(out_dir / REPORT_INDEX, "files")
    write_json(out_dir / REPORT_INDEX, {
        "run": str(run.run_dir), "scenes": [s.scene_id for s in run.scenes],
        "predictions": [{"agent": a.name, "file": str(a.evaluation.predictions),
                         "sha256": a.evaluation.predictions_sha256} for a in agents],
        "config": config.model_dump(mode="json"), "files": sorted(files)})
    for name, data in ui.track(list(files.items()), "writing the report"):
        write_bytes(out_dir / name, data)
    remove_unlisted(out_dir, earlier, files)
    return Report(out_dir, {n: len(d) for n, d in files.items()}, len(run.scenes),
                  sum(len(s.rows) for s in run.scenes), [a.name for a in agents])


def report_files(run: RunFacts, agents: list[Agent], config: ReportConfig) -> dict[str, bytes]:
    """Every file of the report by its name in the report's folder."""
    files = {CSS_FILE: CSS.encode(), JS_FILE: JS.encode(), "index.html": pages.overview_page(run, agents).encode()}
    if agents:
        files["agents.html"] = pages.agents_page(run, agents).encode()
    for scene in run.scenes:
        frame = map_frame(scene.map_png, scene.grids)
        files[pages.map_href("", scene.scene_id)] = scene.map_png.read_bytes()
        files[pages.scene_href("", scene.scene_id)] = pages.scene_page(scene, frame, agents).encode()
        for row in ui.track(scene.rows, f"episode pages of {scene.scene_id}"):
            files[pages.episode_href("", row["episode_id"])] = pages.episode_page(
                scene, row, frame, agents, config.views).encode()
        if config.views:
            files.update(_views(run.run_dir, scene, config))
    return files


def _views(run_dir: Path, scene: SceneFacts, config: ReportConfig) -> dict[str, bytes]:
    """The start and goal view of each of the scene's trajectories, by file name."""
    poses = {}
    for tid, rows in scene.trajectories().items():
        start, goal = start_and_goal(rows[0])
        poses[pages.view_href("", scene.scene_id, tid, "start")] = start
        poses[pages.view_href("", scene.scene_id, tid, "goal")] = goal
    render = RenderConfig(width=THUMBNAIL[0], height=THUMBNAIL[1], renderer=config.renderer)
    return dict(ui.track(render_thumbnails(run_dir, scene.scene_id, poses, render), f"views of {scene.scene_id}",
                         total=len(poses)))
