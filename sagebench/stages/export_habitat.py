"""`export-habitat`: a run's ObjectNav, PointNav and ImageNav episodes as habitat-lab datasets of those tasks, in
habitat's Y-up frame (sagebench.vlnce.tasks).

A command of its own, beside export-vlnce: habitat-lab's task datasets are not VLN-CE's (no vocabulary, no teacher
paths, habitat-lab's own config keys), so export-vlnce's output stays what VLN-CE reads, and each export claims its
folder by its own mark. Reads RUN/episodes/<id>/part-*.parquet and RUN/scenes/<id>/scene.json + meshes/, topdown.npz
and semantic_map.json (what ObjectNav's view points see). Writes OUT/<task>/<split>/<split>.json.gz per goal task
and split, OUT/scenes/<id>/<id>.glb (as export-vlnce writes them) and OUT/habitat_export.json (per task: habitat's
dataset type, data_path and scenes_dir, and the episodes per split; the mark of an export-habitat folder).
Everything is computed before the first byte is written; vln and nogoal rows are left out (habitat-lab has no
dataset format for them).
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pyarrow as pa
from shapely.geometry import Polygon

from sagebench.episodes.shards import read_episodes
from sagebench.episodes.targets import scene_sight
from sagebench.episodes.tasks import row_task
from sagebench.errors import ConfigError, DataError
from sagebench.fileio import dumps_json, write_bytes, write_text
from sagebench.instructions.sight import footprint_points
from sagebench.run_layout import CONTRACT, SEMANTIC_MAP, TOPDOWN, require, run_episodes_dir, run_scene_dir, run_scenes
from sagebench.scene.loader import LoadedScene, load_scene
from sagebench.settings.shared import SPLITS
from sagebench.topdown.grid_file import read_topdown_grids
from sagebench.topdown.semantic_map import read_semantic_map
from sagebench.vlnce.episodes import scene_glb_path
from sagebench.vlnce.glb import scene_glb
from sagebench.vlnce.tasks import HABITAT_TASKS, SceneObjects, task_dataset_bytes

MARKER = "habitat_export.json"
SCENES_DIR = "scenes"


def task_file(task: str, split: str) -> str:
    return f"{task}/{split}/{split}.json.gz"


@dataclass(frozen=True)
class HabitatExport:
    out_dir: Path
    episodes: dict[tuple[str, str], int]  # (task, split) -> episodes written
    scenes: list[str]
    skipped: Counter  # rows of tasks habitat-lab has no dataset for, by task

    def lines(self) -> list[str]:
        out = [f"export-habitat: {sum(self.episodes.values())} episodes, {len(self.scenes)} scene GLB(s) -> "
               f"{self.out_dir}"]
        for task in sorted({t for t, _ in self.episodes}):
            splits = ", ".join(f"{s} {n}" for (t, s), n in self.episodes.items() if t == task)
            out.append(f"  {task} ({HABITAT_TASKS[task]}: {splits}): habitat.dataset.type={HABITAT_TASKS[task]} "
                       f"habitat.dataset.data_path={self.out_dir / task}/{{split}}/{{split}}.json.gz "
                       f"habitat.dataset.scenes_dir={self.out_dir / SCENES_DIR}")
        if self.skipped:
            out.append("left out (no habitat-lab dataset format): "
                       + ", ".join(f"{t} {n}" for t, n in sorted(self.skipped.items())))
        return out


def export_habitat(run_dir: Path, out_dir: Path, *, split: str | None = None) -> HabitatExport:
    """Write the dataset of every goal task and split of the run (or of `split`) into `out_dir`."""
    if split is not None and split not in SPLITS:
        raise ConfigError(f"{split!r} is not a split (one of {', '.join(SPLITS)})", field="--split")
    rows, skipped, categories = _task_rows(Path(run_dir), split)
    groups = {(t, s): [r for r in rows if row_task(r) == t and r["split"] == s] for t in HABITAT_TASKS for s in SPLITS}
    groups = {k: v for k, v in groups.items() if v}
    if not groups:
        what = f"split {split!r}" if split is not None else "the run"
        raise DataError(f"no objectnav, pointnav or imagenav episodes in {what}", path=Path(run_dir))
    scenes = {sid: load_scene(run_scene_dir(run_dir, sid)) for sid in sorted({r["scene_id"] for r in rows})}
    objects = {sid: _scene_objects(run_scene_dir(run_dir, sid), s) for sid, s in scenes.items()}
    files = {task_file(t, s): task_dataset_bytes(t, v, objects, categories) for (t, s), v in groups.items()}
    files.update({f"{SCENES_DIR}/{scene_glb_path(sid)}": scene_glb(s) for sid, s in scenes.items()})
    for rel, data in files.items():
        write_bytes(Path(out_dir) / rel, data)
    write_text(Path(out_dir) / MARKER, dumps_json({"format": 1, "scenes_dir": SCENES_DIR, "tasks": {
        t: {"type": HABITAT_TASKS[t], "data_path": f"{t}/{{split}}/{{split}}.json.gz",
            "episodes": {s: len(v) for (t2, s), v in groups.items() if t2 == t}}
        for t in sorted({t for t, _ in groups})}}))
    return HabitatExport(Path(out_dir), {k: len(v) for k, v in groups.items()}, list(scenes), skipped)


def _scene_objects(scene_dir: Path, scene: LoadedScene) -> SceneObjects:
    """A scene's instances as ObjectNav's goals need them: mesh centres, and the share of each footprint in sight
    from a view point on the scene's map (an instance without a footprint: its centre's)."""
    smap, grids = read_semantic_map(scene_dir / SEMANTIC_MAP), read_topdown_grids(scene_dir / TOPDOWN)
    sight = scene_sight(smap, grids, grids.occupancy)
    centres = {iid: mesh.bounds.mean(axis=0).tolist() for iid, mesh in scene.meshes.items()}
    points = {i.instance_id: footprint_points([Polygon(p[0], p[1:]) for p in i.polygon.coordinates], grids.resolution,
                                              grids.origin) for i in smap.instances if i.polygon.coordinates}
    return SceneObjects(centres, lambda iid, xy: sight.share_seen(xy, points.get(iid, np.array([centres[iid][:2]]))))


def _task_rows(run_dir: Path, split: str | None) -> tuple[list[dict], Counter, list[str]]:
    """The rows of the goal tasks habitat-lab has datasets for (of `split`, when given), the others counted, and the
    goal categories of the run's objectnav rows in every split: one category numbering for all of the run's files,
    as a model trained on one split and evaluated on another needs."""
    rows: list[dict] = []
    skipped: Counter = Counter()
    categories: set[str] = set()
    for sid in run_scenes(run_dir, having="episodes"):
        require(CONTRACT["export_habitat"].reads, run_dir, sid)
        try:
            table = read_episodes(run_episodes_dir(run_dir, sid))
        except (OSError, pa.ArrowException) as err:
            raise DataError(f"cannot read episode shards: {err}", path=run_episodes_dir(run_dir, sid)) from None
        for row in table.to_pylist():
            if row_task(row) == "objectnav":
                categories.add(row["goal_category"])
            if split is not None and row["split"] != split:
                continue
            if row_task(row) in HABITAT_TASKS:
                rows.append(row)
            else:
                skipped[row_task(row)] += 1
    return rows, skipped, sorted(categories)
