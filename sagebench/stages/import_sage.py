"""`import-sage-episodes`: SAGE-Bench's GVLN episodes for a scene of a run -> sagebench episode rows, so that SAGE-3D's
own test episodes run and are scored in sagebench's closed loop (rollout, evaluate).

Reads FILE (a GVLN trajectory file, sagebench.gvln.episodes) and RUN/scenes/<id>/scene.json, topdown.npz and
semantic_map.json (objectnav's goal viewpoints, where the file has none) of the scene it is for: the one whose id
is its `scene_name` or ends with "_<scene_name>" (an imported InteriorGS scene `0001_839920` is SAGE-3D's
`839920`), or --scene. The file's values are checked as generated episodes are (its path points on the navigable
map, moved onto it from at most SNAP_M away). Writes
RUN/episodes/<id>/part-<split>-NNNNN.parquet, replacing that scene's episodes whole (a staged directory renamed
into place).
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass
from pathlib import Path

from sagebench.astar.sampling import GridMap
from sagebench.episodes.shards import write_shards
from sagebench.episodes.task_rows import scene_map
from sagebench.episodes.tasks import schema_for
from sagebench.errors import ConfigError, DataError
from sagebench.fileio import staged_dir
from sagebench.gvln.episodes import SNAP_M, read_gvln, rows_from_gvln
from sagebench.input_files import read_input
from sagebench.metrics import NavigableMap
from sagebench.run_layout import (
    CONTRACT, SCENE_FILE, SCENES, SEMANTIC_MAP, TOPDOWN, require, run_episodes_dir, run_scene_dir,
)
from sagebench.scene.loader import parse_spec
from sagebench.settings.gen_trajectories import TaskConfig
from sagebench.settings.import_sage_episodes import SageImportConfig
from sagebench.stamps import check_reads
from sagebench.topdown.grid_file import read_topdown_grids
from sagebench.topdown.semantic_map import read_semantic_map

SHARD_BYTES = 128 * 2**20


@dataclass(frozen=True)
class SageImport:
    scene_id: str
    out_dir: Path
    trajectories: int
    rows: int
    skipped: Counter
    snapped: int  # path points moved onto the navigable map
    snapped_ends: Counter  # of them, samples' starts and goals ("start", "goal")
    snapped_max_m: float  # the farthest any of them moved

    def lines(self) -> list[str]:
        moved = (f"{self.snapped} path points snapped onto the navigable map (within {SNAP_M:g} m"
                 + (f"; {self.snapped_ends['start']} starts, {self.snapped_ends['goal']} goals, the farthest "
                    f"{self.snapped_max_m:.2f} m" if self.snapped else "") + ")")
        out = [f"import-sage-episodes {self.scene_id}: {self.trajectories} trajectories, {self.rows} episode rows, "
               f"{moved} -> {self.out_dir}"]
        if self.skipped:
            out.append("left out instructions of types sagebench does not know: "
                       + ", ".join(f"{k} {v}" for k, v in sorted(self.skipped.items())))
        return out


def import_sage_episodes(path: Path, run_dir: Path, config: SageImportConfig = SageImportConfig(), *,
                         scene_id: str | None = None) -> SageImport:
    """Read the GVLN file `path` and write its episodes into the run for their scene (`config` for what the
    file does not say); the scene's scene.json must be the one build-scene stamped."""
    scene = read_gvln(path)
    sid = scene_id or _scene_for(scene.scene_name, Path(run_dir), path)
    require(CONTRACT["import_sage"].reads, run_dir, sid)
    check_reads("import_sage", run_dir, sid)
    scene_dir = run_scene_dir(run_dir, sid)
    spec = parse_spec(read_input(scene_dir / SCENE_FILE), scene_dir / SCENE_FILE)
    grids = read_topdown_grids(scene_dir / TOPDOWN)
    navmap = NavigableMap(grids.navigable, grids.resolution, grids.origin, snap_radius=SNAP_M)
    grid = GridMap(grids.navigable, grids.resolution, grids.origin, float(spec.floor_height), grids.anchors)
    goal_maps = read_semantic_map(scene_dir / SEMANTIC_MAP), scene_map(grid, {})  # objectnav's viewpoints
    budget = TaskConfig().nogoal_budget_s, TaskConfig().nogoal_budget_steps
    got = rows_from_gvln(scene, spec, navmap, goal_maps, goal_radius=config.goal_radius, split=config.split,
                         budget=budget)
    if not got.rows:
        raise DataError("no episode to import (no sample, or every instruction of a type sagebench does not know)",
                        path=path)
    out = run_episodes_dir(run_dir, sid)
    with staged_dir(out) as tmp:
        write_shards(got.rows, tmp, SHARD_BYTES, schema_for(r["task"] for r in got.rows))
    return SageImport(sid, out, len({r["trajectory_id"] for r in got.rows}), len(got.rows), got.skipped, got.snapped,
                      got.snapped_ends, got.snapped_max_m)


def _scene_for(name: str, run_dir: Path, path: Path) -> str:
    """The run's scene whose id is `name` or ends with "_<name>"; exactly one, else a ConfigError."""
    built = sorted(p.name for p in (run_dir / SCENES).glob("*") if (p / SCENE_FILE).is_file())
    found = [s for s in built if s == name or s.endswith(f"_{name}")]
    if len(found) != 1:
        what = "no scene" if not found else f"scenes {', '.join(found)}"
        raise ConfigError(f"the file is for scene {name!r}, and {run_dir / SCENES} has {what} of that name; "
                          "name the scene with --scene", path=path, field="scene_name")
    return found[0]
