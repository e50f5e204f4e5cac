"""`export-sage`: a run's episodes as SAGE-3D GVLN trajectory files, one per scene and task (sagebench.gvln).

Reads RUN/episodes/<id>/part-*.parquet, RUN/scenes/<id>/scene.json and semantic_map.json (the objects that name a
room goal's end: sagebench.gvln.room_goals; a trajectory whose goal is a room with no object near is left out and
counted). Writes OUT/<id>/trajectories_<id>.json
per scene for its vln episodes (the name SAGE-3D's trajectory generator gives its files), and
OUT/<task-type>/<id>/trajectories_<id>.json for those of each other task, <task-type> the `run_benchmark.py
--task-type` that reads them (nogoalnav, objectnav, pointnav, imgnav: sagebench.gvln.tasks); and
OUT/sage_export.json (what was exported: the mark of an export-sage folder, which a later export-sage may write
again). Everything is computed before the first byte is written; the run is not changed.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import pyarrow as pa

from sagebench.episodes.shards import read_episodes
from sagebench.errors import DataError
from sagebench.fileio import dumps_json, write_text
from sagebench.episodes.tasks import VLN, row_task
from sagebench.gvln.episodes import gvln_document, item_names
from sagebench.gvln.room_goals import BOX_SLACK_M, SAGE_REACH_M, room_goal_ends
from sagebench.gvln.tasks import SAGE_TASK_TYPE
from sagebench.run_layout import (
    CONTRACT, SCENE_FILE, SEMANTIC_MAP, require, run_episodes_dir, run_scene_dir, run_scenes,
)
from sagebench.scene.loader import parse_spec
from sagebench.settings.shared import TASKS
from sagebench.topdown.semantic_map import read_semantic_map


MARKER = "sage_export.json"


def gvln_file(scene_id: str, task: str = VLN) -> str:
    """A scene's file of one task's episodes, relative to OUT."""
    tail = f"{scene_id}/trajectories_{scene_id}.json"
    return tail if task == VLN else f"{SAGE_TASK_TYPE[task]}/{tail}"


@dataclass(frozen=True)
class SageExport:
    out_dir: Path
    files: dict[tuple[str, str], tuple[int, int]]  # (scene id, task) -> (trajectories, instructions)
    left_out: dict[str, int]  # scene id -> trajectories left out: their goal a room with no object near

    def lines(self) -> list[str]:
        t = sum(v[0] for v in self.files.values())
        i = sum(v[1] for v in self.files.values())
        scenes = len({sid for sid, _ in self.files})
        out = [f"export-sage: {t} trajectories, {i} instructions, {scenes} scene(s) -> {self.out_dir}"]
        if sum(self.left_out.values()):
            out.append(f"left out {sum(self.left_out.values())} trajectories whose goal is a room with no object "
                       f"within {SAGE_REACH_M - BOX_SLACK_M:g} m of its goal (SAGE-Bench scores a goal by an object): "
                       + ", ".join(f"{sid} {n}" for sid, n in sorted(self.left_out.items()) if n))
        for task in sorted({task for _, task in self.files if task != VLN}, key=TASKS.index):
            out.append(f"{task}: {self.out_dir / SAGE_TASK_TYPE[task]} (run_benchmark.py --task-type "
                       f"{SAGE_TASK_TYPE[task]})")
        return out


def export_sage(run_dir: Path, out_dir: Path, *, scene_id: str | None = None) -> SageExport:
    """Write every scene's (or `scene_id`'s) episodes as a GVLN file under `out_dir`."""
    docs: dict[tuple[str, str], dict] = {}  # (scene id, task) -> GVLN document
    left_out: dict[str, int] = {}
    for sid in run_scenes(Path(run_dir), scene_id, having="episodes"):
        require(CONTRACT["export_sage"].reads, run_dir, sid)
        try:
            rows = read_episodes(run_episodes_dir(run_dir, sid)).to_pylist()
        except (OSError, pa.ArrowException) as err:
            raise DataError(f"cannot read episode shards: {err}", path=run_episodes_dir(run_dir, sid)) from None
        spec_path = run_scene_dir(run_dir, sid) / SCENE_FILE
        spec = parse_spec(spec_path.read_text(encoding="utf-8"), spec_path)
        ends, none = room_goal_ends(rows, read_semantic_map(run_scene_dir(run_dir, sid) / SEMANTIC_MAP),
                                    item_names(spec))
        left_out[sid] = len(none)
        rows = [r for r in rows if r["trajectory_id"] not in none]
        for task in sorted({row_task(r) for r in rows}, key=TASKS.index):
            docs[sid, task] = gvln_document(sid, [r for r in rows if row_task(r) == task], spec, ends)
    counts = {key: (len(d["scenes"][0]["samples"]), sum(len(s["instructions"]) for s in d["scenes"][0]["samples"]))
              for key, d in docs.items()}
    for (sid, task), doc in docs.items():
        write_text(Path(out_dir) / gvln_file(sid, task), dumps_json(doc))
    write_text(Path(out_dir) / MARKER, dumps_json(_marker(counts, left_out)))
    return SageExport(Path(out_dir), counts, left_out)


def _marker(counts: dict[tuple[str, str], tuple[int, int]], left_out: dict[str, int]) -> dict:
    """sage_export.json: each vln file by scene (as before tasks existed), each other task's under "tasks", by
    its --task-type; the trajectories left out by scene, where any were (their goal a room with no object near)."""
    files: dict[str, dict] = {}
    tasks: dict[str, dict] = {}
    for (sid, task), (t, i) in counts.items():
        entry = {"file": gvln_file(sid, task), "trajectories": t, "instructions": i}
        (files if task == VLN else tasks.setdefault(SAGE_TASK_TYPE[task], {}))[sid] = entry
    left = {sid: n for sid, n in left_out.items() if n}
    return {"format": 1, "files": files, **({"tasks": tasks} if tasks else {}),
            **({"room_goals_left_out": left} if left else {})}
