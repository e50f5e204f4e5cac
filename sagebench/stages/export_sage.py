"""`export-sage`: a run's episodes as SAGE-3D GVLN trajectory files, one per scene and task (sagebench.gvln).

Reads RUN/episodes/<id>/part-*.parquet and RUN/scenes/<id>/scene.json. Writes OUT/<id>/trajectories_<id>.json
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
from sagebench.gvln.episodes import gvln_document
from sagebench.gvln.tasks import SAGE_TASK_TYPE
from sagebench.run_layout import CONTRACT, SCENE_FILE, require, run_episodes_dir, run_scene_dir, run_scenes
from sagebench.scene.loader import parse_spec
from sagebench.settings.shared import TASKS


MARKER = "sage_export.json"


def gvln_file(scene_id: str, task: str = VLN) -> str:
    """A scene's file of one task's episodes, relative to OUT."""
    tail = f"{scene_id}/trajectories_{scene_id}.json"
    return tail if task == VLN else f"{SAGE_TASK_TYPE[task]}/{tail}"


@dataclass(frozen=True)
class SageExport:
    out_dir: Path
    files: dict[tuple[str, str], tuple[int, int]]  # (scene id, task) -> (trajectories, instructions)

    def lines(self) -> list[str]:
        t = sum(v[0] for v in self.files.values())
        i = sum(v[1] for v in self.files.values())
        scenes = len({sid for sid, _ in self.files})
        out = [f"export-sage: {t} trajectories, {i} instructions, {scenes} scene(s) -> {self.out_dir}"]
        for task in sorted({task for _, task in self.files if task != VLN}, key=TASKS.index):
            out.append(f"{task}: {self.out_dir / SAGE_TASK_TYPE[task]} (run_benchmark.py --task-type "
                       f"{SAGE_TASK_TYPE[task]})")
        return out


def export_sage(run_dir: Path, out_dir: Path, *, scene_id: str | None = None) -> SageExport:
    """Write every scene's (or `scene_id`'s) episodes as a GVLN file under `out_dir`."""
    docs: dict[tuple[str, str], dict] = {}  # (scene id, task) -> GVLN document
    for sid in run_scenes(Path(run_dir), scene_id, having="episodes"):
        require(CONTRACT["export_sage"].reads, run_dir, sid)
        try:
            rows = read_episodes(run_episodes_dir(run_dir, sid)).to_pylist()
        except (OSError, pa.ArrowException) as err:
            raise DataError(f"cannot read episode shards: {err}", path=run_episodes_dir(run_dir, sid)) from None
        spec_path = run_scene_dir(run_dir, sid) / SCENE_FILE
        spec = parse_spec(spec_path.read_text(encoding="utf-8"), spec_path)
        for task in sorted({row_task(r) for r in rows}, key=TASKS.index):
            docs[sid, task] = gvln_document(sid, [r for r in rows if row_task(r) == task], spec)
    counts = {key: (len(d["scenes"][0]["samples"]), sum(len(s["instructions"]) for s in d["scenes"][0]["samples"]))
              for key, d in docs.items()}
    for (sid, task), doc in docs.items():
        write_text(Path(out_dir) / gvln_file(sid, task), dumps_json(doc))
    write_text(Path(out_dir) / MARKER, dumps_json(_marker(counts)))
    return SageExport(Path(out_dir), counts)


def _marker(counts: dict[tuple[str, str], tuple[int, int]]) -> dict:
    """sage_export.json: each vln file by scene (as before tasks existed), each other task's under "tasks", by
    its --task-type."""
    files: dict[str, dict] = {}
    tasks: dict[str, dict] = {}
    for (sid, task), (t, i) in counts.items():
        entry = {"file": gvln_file(sid, task), "trajectories": t, "instructions": i}
        (files if task == VLN else tasks.setdefault(SAGE_TASK_TYPE[task], {}))[sid] = entry
    return {"format": 1, "files": files, **({"tasks": tasks} if tasks else {})}
