"""`validate`: replay every trajectory of a run in MuJoCo, score it, and spot-check appearance against physics.

Reads RUN/scenes/<id>/{scene.json, scene.xml, colliders/, gaussians.ply, topdown.npz} and
RUN/episodes/<id>/part-*.parquet (Base_Action sentences are executed literally against topdown.npz's occupancy).
A nogoal trajectory has no path to replay: its start pose is checked (validation/checks.py).
Writes RUN/validation/<id>/part-00000.parquet (one row per trajectory) and RUN/reports/<id>/: report.json
(counts, failures by reason, metric distributions, alignment per frame), frames/*.png and
frames/contact_sheet.png; each directory whole.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from sagebench import ui
from sagebench.fileio import dumps_json, staged_dir, write_bytes, write_text
from sagebench.episodes.load import Trajectory, read_trajectories
from sagebench.episodes.tasks import NOGOAL
from sagebench.instructions.execution import BlockedMap
from sagebench.settings.validate import ValidateConfig
from sagebench.metrics.coverage import main_region
from sagebench.topdown.grid_file import TopdownGrids, read_topdown_grids
from sagebench.replay.physics import ReplayModel, ReplayRecord, replay_batch, start_penetration
from sagebench.replay.scene_model import open_replay_model
from sagebench.run_layout import (
    CONTRACT, EPISODES, FRAMES, GAUSSIANS, REPORT, SCENE_FILE, SCENES, TOPDOWN, VALIDATION_SHARD, require,
    run_episodes_dir, run_reports_dir, run_scene_dir, run_scenes, run_validation_dir,
)
from sagebench.scene.loader import parse_spec
from sagebench.splats.ply import read_ply
from sagebench.stamps import check_stamped, stamped_places
from sagebench.validation.checks import Verdict, base_action_executable, judge, judge_start
from sagebench.validation.frames import FrameCheck, pick_frames, spot_checks
from sagebench.validation.ledger import check_listed
from sagebench.validation.report import report, table_bytes
from sagebench.validation.usd_stage import check_stage


@dataclass(frozen=True)
class SceneValidation:
    scene_id: str
    out_dir: Path
    trajectories: int
    episodes: int
    failures: list[tuple[str, tuple[str, ...]]]  # (trajectory_id, reasons)
    frames: list[FrameCheck]
    alignment_ok: bool
    seconds: float

    @property
    def passed(self) -> bool:
        return not self.failures and self.alignment_ok

    def summary(self) -> str:
        worst = max((f.median_abs_diff for f in self.frames if np.isfinite(f.median_abs_diff)), default=float("nan"))
        rate = self.trajectories / self.seconds if self.seconds > 0 else float("inf")
        return (f"validate {self.scene_id}: {self.trajectories - len(self.failures)}/{self.trajectories} trajectories "
                f"pass ({self.episodes} episodes, {rate:.0f} replays/s); alignment "
                f"{'ok' if self.alignment_ok else 'FAILED'} on {len(self.frames)} frames (worst median "
                f"{worst:.3f} m) -> {self.out_dir}")


def validate_run(run_dir: Path, config: ValidateConfig = ValidateConfig(), *, scene_id: str | None = None,
                 against_records: bool = True) -> list[SceneValidation]:
    """Validate every scene of the run (or `scene_id`); the inputs of all scenes are checked (check_inputs)
    before any write. `sagebench run` validates before it writes its manifest, and its stamps vouch for the
    inputs, so it passes `against_records` False."""
    run_dir = Path(run_dir)
    ids = run_scenes(run_dir, scene_id, having="episodes")
    for sid in ids:
        check_inputs(run_dir, sid, against_records=against_records)
    return [validate_scene(run_dir, sid, config) for sid in ids]


def check_inputs(run_dir: Path, scene_id: str, *, against_records: bool = True) -> None:
    """What validate reads for the scene is present and the USD stage whole; with `against_records`, every file
    the run's manifest.json lists for the scene is unchanged, or when it lists none (a run made stage by stage
    has no manifest), every file the scene's stamps list but validate's own outputs, which it replaces."""
    require(CONTRACT["validate"].reads, run_dir, scene_id)
    if against_records and not check_listed(run_dir, [f"{EPISODES}/{scene_id}/", f"{SCENES}/{scene_id}/"]):
        check_stamped(run_dir, scene_id, stamped_places(run_dir, scene_id, besides="validate"))
    spec_path = run_scene_dir(run_dir, scene_id) / SCENE_FILE
    spec = parse_spec(spec_path.read_text(encoding="utf-8"), spec_path)
    check_stage(run_scene_dir(run_dir, scene_id), {o.instance_id: o.category for o in spec.objects})


def validate_scene(run_dir: Path, scene_id: str, config: ValidateConfig) -> SceneValidation:
    """Replay, judge and spot-check one scene; writes RUN/validation/<scene_id>/ whole."""
    scene_dir = run_scene_dir(run_dir, scene_id)
    trajectories = read_trajectories(run_episodes_dir(run_dir, scene_id))
    rm = open_replay_model(run_dir, scene_id, replay=config.replay)  # the agent the scene's map was built for
    start = time.perf_counter()
    with ui.working(f"validate {scene_id}: replaying {len(trajectories)} trajectories"):
        verdicts, records = _verdicts(rm, trajectories, read_topdown_grids(scene_dir / TOPDOWN), config)
    seconds = time.perf_counter() - start
    replayed = sorted(records)
    picks = [(trajectories[replayed[i]], records[replayed[i]]) for i in pick_frames(len(replayed), config)]
    frames, pngs = spot_checks(read_ply(scene_dir / GAUSSIANS), rm, picks, config) if picks else ([], {})
    alignment_ok = all(f.problem is None for f in frames)
    out_dir = run_validation_dir(run_dir, scene_id)
    with staged_dir(run_reports_dir(run_dir, scene_id)) as tmp:
        for name, png in pngs.items():
            write_bytes(tmp / FRAMES / name, png)
        write_text(tmp / REPORT, dumps_json(report(scene_id, trajectories, verdicts, frames, alignment_ok, config)))
    with staged_dir(out_dir) as tmp:
        write_bytes(tmp / VALIDATION_SHARD, table_bytes(scene_id, trajectories, verdicts))
    failures = [(t.trajectory_id, v.reasons) for t, v in zip(trajectories, verdicts) if v.reasons]
    return SceneValidation(scene_id=scene_id, out_dir=out_dir, trajectories=len(trajectories),
                           episodes=sum(len(t.episode_ids) for t in trajectories), failures=failures,
                           frames=frames, alignment_ok=alignment_ok, seconds=seconds)


def _verdicts(rm: ReplayModel, trajectories: list[Trajectory], grids: TopdownGrids, config: ValidateConfig
              ) -> tuple[list[Verdict], dict[int, ReplayRecord]]:
    """Each trajectory's verdict, its reference path replayed (a nogoal one: its start pose checked, as it has no
    path), and the replays by trajectory index."""
    replayed = [i for i, t in enumerate(trajectories) if t.task != NOGOAL]
    records = dict(zip(replayed, replay_batch(rm, [trajectories[i].reference_path for i in replayed],
                                              threads=config.workers), strict=True))
    blocked = BlockedMap(grids.occupancy != 0, grids.resolution, grids.origin)
    main = main_region(grids.navigable)
    verdicts = []
    for i, t in enumerate(trajectories):
        if i not in records:
            verdicts.append(judge_start(on_map=_on(main, grids, t.reference_path[0]),
                                        penetration=start_penetration(rm, t.reference_path[0]), config=config.checks))
            continue
        verdicts.append(judge(records[i], t.reference_path, t.goal, goal_radius=t.goal_radius,
                              geodesic_distance=t.geodesic_distance, timestep=rm.timestep, config=config.checks,
                              executable=base_action_executable(t, blocked)))
    return verdicts, records


def _on(cells: np.ndarray, grids: TopdownGrids, pose: np.ndarray) -> bool:
    """Whether the point (x, y) of `pose` lies on a True cell of `cells` (a [H, W] map of `grids`' frame)."""
    col, row = np.floor((np.asarray(pose[:2]) - np.asarray(grids.origin)) / grids.resolution).astype(int)
    return bool(0 <= row < cells.shape[0] and 0 <= col < cells.shape[1] and cells[row, col])
