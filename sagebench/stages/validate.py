"""`validate`: replay every trajectory of a run in MuJoCo, score it, and spot-check appearance against physics.

Reads RUN/scenes/<id>/{scene.json, scene.xml, colliders/, gaussians.ply, topdown.npz} and
RUN/episodes/<id>/part-*.parquet (Base_Action sentences are executed literally against topdown.npz's occupancy).
Writes RUN/validation/<id>/ whole: part-00000.parquet (one row per trajectory), report.json (counts, failures
by reason, metric distributions, alignment per frame), frames/*.png and frames/contact_sheet.png.
"""

from __future__ import annotations

import io
from dataclasses import dataclass
from pathlib import Path

import cv2
import mujoco
import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
from pydantic import BaseModel, ConfigDict, Field

from sagebench import ui
from sagebench.config import AgentConfig, from_options
from sagebench.fileio import dumps_json, staged_dir, write_bytes, write_text
from sagebench.episodes.load import Trajectory, read_trajectories, scene_ids
from sagebench.instructions.execution import BlockedMap, execute_sentence
from sagebench.render.backends import RendererChoice
from sagebench.topdown.grid_file import read_topdown_grids
from sagebench.replay.physics import AGENT_BODY, ReplayConfig, ReplayRecord, replay_batch
from sagebench.replay.scene_model import open_replay_model
from sagebench.run_layout import (
    CONTACT_SHEET, CONTRACT, FRAMES, GAUSSIANS, REPORT, TOPDOWN, VALIDATION_SHARD, require, run_episodes_dir, run_scene_dir,
    run_validation_dir,
)
from sagebench.validation.checks import REASONS, CheckConfig, Verdict, judge

FRAME_POINTS = ("start", "middle", "goal")
METRICS = ("csr", "icp", "ps", "ndtw", "final_distance", "path_length", "max_penetration", "max_deviation", "steps")


class ValidateConfig(BaseModel):
    """Settings of validate (defaults here, nowhere else); the CLI maps its options onto these fields."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    agent: AgentConfig = AgentConfig()
    replay: ReplayConfig = ReplayConfig()
    checks: CheckConfig = CheckConfig()
    frames_per_scene: int = Field(default=3, ge=0, description="Trajectories per scene with spot-check frames.")
    depth_tolerance: float = Field(default=0.10, gt=0, description="Largest median |splat - collider depth| per frame, m.")
    frame_width: int = Field(default=320, ge=8, le=4096, description="Spot-check frame width, px.")
    frame_height: int = Field(default=240, ge=8, le=4096, description="Spot-check frame height, px.")
    ray_stride: int = Field(default=8, ge=1, description="Collider rays are cast every this many pixels.")
    min_alpha: float = Field(default=0.5, gt=0, le=1, description="Splat pixels this opaque are compared.")
    min_compared_fraction: float = Field(default=0.25, gt=0, le=1, description=(
        "A frame whose compared pixels (opaque splat and a collider hit) are fewer than this fraction of the "
        "sampled ones fails alignment."))
    workers: int = Field(default=2, ge=1, description="Threads stepping the MuJoCo replays.")
    seed: int = Field(default=0, description="Picks the spot-checked trajectories.")
    renderer: RendererChoice = Field(default="cpu", description=(
        "Renderer of the spot-check frames: cpu (the reference), gsplat (CUDA GPU; the instance-id frames still "
        "come from the CPU renderer) or auto."))


# validate's options and the ValidateConfig fields they set (their defaults and error names come from here)
OPTIONS = {"--frames-per-scene": "frames_per_scene", "--depth-tolerance": "depth_tolerance", "--workers": "workers",
           "--renderer": "renderer"}


def make_config(**fields: object) -> ValidateConfig:
    """A ValidateConfig from the options given (None = keep the default); a bad value is a ConfigError."""
    return from_options(ValidateConfig, fields, OPTIONS)


@dataclass(frozen=True)
class FrameCheck:
    file: str
    trajectory_id: str
    point: str  # start / middle / goal
    median_abs_diff: float  # m; NaN when no pixel could be compared
    compared: int
    sampled: int
    problem: str | None  # why the frame fails alignment (replay.alignment.frame_problem), None when it passes


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


def validate_run(run_dir: Path, config: ValidateConfig = ValidateConfig(), *, scene_id: str | None = None
                 ) -> list[SceneValidation]:
    """Validate every scene of the run (or `scene_id`); inputs are checked for all scenes before any write."""
    run_dir = Path(run_dir)
    ids = scene_ids(run_dir, scene_id)
    for sid in ids:
        require(CONTRACT["validate"].reads, run_dir, sid)
    return [validate_scene(run_dir, sid, config) for sid in ids]


def validate_scene(run_dir: Path, scene_id: str, config: ValidateConfig) -> SceneValidation:
    """Replay, judge and spot-check one scene; writes RUN/validation/<scene_id>/ whole."""
    import time

    scene_dir = run_scene_dir(run_dir, scene_id)
    trajectories = read_trajectories(run_episodes_dir(run_dir, scene_id))
    rm = open_replay_model(run_dir, scene_id, agent=config.agent, replay=config.replay)
    start = time.perf_counter()
    records = replay_batch(rm, [t.reference_path for t in trajectories], threads=config.workers)
    grids = read_topdown_grids(scene_dir / TOPDOWN)
    blocked = BlockedMap(grids.occupancy != 0, grids.resolution, grids.origin)
    verdicts = [judge(rec, t.reference_path, t.goal, goal_radius=t.goal_radius,
                      geodesic_distance=t.geodesic_distance, timestep=rm.timestep, config=config.checks,
                      executable=base_action_executable(t, blocked))
                for rec, t in zip(records, trajectories)]
    seconds = time.perf_counter() - start
    picks = _pick(len(trajectories), config)
    out_dir = run_validation_dir(run_dir, scene_id)
    with staged_dir(out_dir) as tmp:
        frames = _spot_checks(scene_dir, rm, [(trajectories[i], records[i]) for i in picks], tmp / FRAMES, config)
        alignment_ok = all(f.problem is None for f in frames)
        write_bytes(tmp / VALIDATION_SHARD, _table_bytes(scene_id, trajectories, verdicts))
        write_text(tmp / REPORT, dumps_json(_report(scene_id, trajectories, verdicts, frames, alignment_ok, config)))
    failures = [(t.trajectory_id, v.reasons) for t, v in zip(trajectories, verdicts) if v.reasons]
    return SceneValidation(scene_id=scene_id, out_dir=out_dir, trajectories=len(trajectories),
                           episodes=sum(len(t.episode_ids) for t in trajectories), failures=failures,
                           frames=frames, alignment_ok=alignment_ok, seconds=seconds)


def base_action_executable(traj: Trajectory, blocked: BlockedMap) -> bool:
    """Whether every Base_Action sentence of `traj` ends within its goal radius without crossing `blocked`."""
    start = traj.reference_path[0]
    return all(execute_sentence(s, start[:2], float(start[3]), traj.goal[:2], blocked).ok(traj.goal_radius)
               for s in traj.base_action)


def _pick(n: int, config: ValidateConfig) -> list[int]:
    k = min(n, config.frames_per_scene)
    return sorted(np.random.default_rng(config.seed).choice(n, size=k, replace=False).tolist()) if k else []


# ---------------------------------------------------------------- outputs


def _table_bytes(scene_id: str, trajectories: list[Trajectory], verdicts: list[Verdict]) -> bytes:
    rows = [{"scene_id": scene_id, "trajectory_id": t.trajectory_id, "episode_ids": list(t.episode_ids),
             "passed": v.passed, "reasons": list(v.reasons), "reached_goal": v.reached_goal,
             "collision_free": v.collision_free, "final_distance": v.final_distance, "csr": v.csr, "icp": v.icp,
             "ps": v.ps, "ndtw": v.ndtw, "path_length": v.path_length, "reference_length": v.reference_length,
             "max_penetration": v.max_penetration, "max_deviation": v.max_deviation,
             "contact_steps": v.contact_steps, "steps": v.steps, "duration_s": v.duration, "outcome": v.outcome}
            for t, v in zip(trajectories, verdicts)]
    table = pa.Table.from_pylist(rows, schema=VALIDATION_SCHEMA)
    sink = io.BytesIO()
    pq.write_table(table, sink, compression="zstd", store_schema=True)
    return sink.getvalue()


VALIDATION_SCHEMA = pa.schema([
    ("scene_id", pa.string()), ("trajectory_id", pa.string()), ("episode_ids", pa.list_(pa.string())),
    ("passed", pa.bool_()), ("reasons", pa.list_(pa.string())), ("reached_goal", pa.bool_()),
    ("collision_free", pa.bool_()), ("final_distance", pa.float64()), ("csr", pa.float64()), ("icp", pa.float64()),
    ("ps", pa.float64()), ("ndtw", pa.float64()), ("path_length", pa.float64()), ("reference_length", pa.float64()),
    ("max_penetration", pa.float64()), ("max_deviation", pa.float64()), ("contact_steps", pa.int64()),
    ("steps", pa.int64()), ("duration_s", pa.float64()), ("outcome", pa.string()),
])


def _distribution(values: np.ndarray) -> dict[str, float]:
    if not len(values):
        return {}
    q = np.percentile(values, [0, 5, 50, 95, 100])
    return {"mean": _r(values.mean()), "min": _r(q[0]), "p05": _r(q[1]), "p50": _r(q[2]), "p95": _r(q[3]),
            "max": _r(q[4])}


def _r(x: float) -> float | None:
    return round(float(x), 6) if np.isfinite(x) else None


def _report(scene_id: str, trajectories: list[Trajectory], verdicts: list[Verdict], frames: list[FrameCheck],
            alignment_ok: bool, config: ValidateConfig) -> dict:
    failed = [(t, v) for t, v in zip(trajectories, verdicts) if v.reasons]
    return {
        "scene_id": scene_id,
        "trajectories": len(trajectories),
        "episodes": sum(len(t.episode_ids) for t in trajectories),
        "passed": len(trajectories) - len(failed),
        "failed": len(failed),
        "failures_by_reason": {r: sum(r in v.reasons for _, v in failed) for r in REASONS},
        "failures": [{"trajectory_id": t.trajectory_id, "episode_ids": list(t.episode_ids), "reasons": list(v.reasons)}
                     for t, v in failed],
        "metrics": {m: _distribution(np.array([getattr(v, m) for v in verdicts], dtype=np.float64)) for m in METRICS},
        "alignment": {"ok": alignment_ok, "depth_tolerance": config.depth_tolerance,
                      "min_compared_fraction": config.min_compared_fraction,
                      "frames": [{"file": f.file, "trajectory_id": f.trajectory_id, "point": f.point,
                                  "median_abs_diff": _r(f.median_abs_diff), "compared_pixels": f.compared,
                                  "sampled_pixels": f.sampled, "problem": f.problem}
                                 for f in frames]},
        "config": config.model_dump(mode="json"),
    }


# ---------------------------------------------------------------- spot-check frames


def _spot_checks(scene_dir: Path, rm, picks: list[tuple[Trajectory, ReplayRecord]], frames_dir: Path,
                 config: ValidateConfig) -> list[FrameCheck]:
    """Render start/middle/goal of each picked replay, compare its depth with the colliders, write PNGs."""
    if not picks:
        return []
    from sagebench.replay.alignment import collider_depth, compare_depth, frame_problem, pixel_grid
    from sagebench.render.backends import CpuRenderer, open_renderer
    from sagebench.render.camera import agent_camera
    from sagebench.splats.ply import read_ply

    gaussians = read_ply(scene_dir / GAUSSIANS)
    renderer = open_renderer(gaussians, config.renderer, needs=("rgb", "depth", "alpha"))
    data = mujoco.MjData(rm.model)
    mujoco.mj_kinematics(rm.model, data)
    agent_body = rm.model.body(AGENT_BODY).id
    checks, rows = [], []
    for traj, rec in ui.track(picks, "spot-check frames"):
        tiles = []
        for point, k in zip(FRAME_POINTS, (0, len(rec.poses) // 2, len(rec.poses) - 1)):
            x, y, _, yaw = rec.poses[k]
            cam = agent_camera(x, y, yaw, floor_z=rm.floor_z, camera_height=config.agent.camera_height,
                               hfov_deg=config.agent.hfov_deg, width=config.frame_width, height=config.frame_height)
            frame = renderer.render([cam])[0]
            grid = pixel_grid(cam, config.ray_stride)
            a = compare_depth(frame.depth, frame.alpha, grid,
                              collider_depth(rm.model, data, cam, grid, bodyexclude=agent_body),
                              min_alpha=config.min_alpha)
            instance = frame.instance if frame.instance is not None else CpuRenderer(gaussians).render([cam])[0].instance
            rgb, ids = _rgb8(frame.rgb), _id_colours(instance)
            name = f"{traj.trajectory_id}_{point}"
            write_bytes(frames_dir / f"{name}.png", _png(rgb))
            write_bytes(frames_dir / f"{name}_ids.png", _png(ids))
            problem = frame_problem(a, tolerance=config.depth_tolerance, min_fraction=config.min_compared_fraction)
            checks.append(FrameCheck(f"{FRAMES}/{name}.png", traj.trajectory_id, point, a.median_abs_diff, a.compared,
                                     a.sampled, problem))
            tiles += [_label(rgb, f"{point}  d={a.median_abs_diff:.3f} m"), _label(ids, traj.trajectory_id)]
        rows.append(np.hstack(tiles))
    write_bytes(frames_dir / CONTACT_SHEET, _png(np.vstack(rows)))
    return checks


def _rgb8(rgb: np.ndarray) -> np.ndarray:
    return (np.clip(rgb, 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8)


def _id_colours(instance: np.ndarray) -> np.ndarray:
    """[H, W] instance ids -> [H, W, 3] uint8, a fixed colour per id (golden-ratio hues), black for 0."""
    ids = np.asarray(instance, dtype=np.int64)
    hue = ((ids * 0.618033988749895) % 1.0 * 179).astype(np.uint8)
    hsv = np.stack([hue, np.full_like(hue, 200), np.where(ids > 0, 230, 0).astype(np.uint8)], axis=-1)
    return cv2.cvtColor(hsv, cv2.COLOR_HSV2RGB)


def _label(img: np.ndarray, text: str) -> np.ndarray:
    out = img.copy()
    cv2.rectangle(out, (0, 0), (out.shape[1], 16), (0, 0, 0), -1)
    cv2.putText(out, text, (3, 12), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (255, 255, 255), 1, cv2.LINE_AA)
    return out


def _png(rgb: np.ndarray) -> bytes:
    ok, buf = cv2.imencode(".png", np.ascontiguousarray(rgb[:, :, ::-1]))
    if not ok:
        raise RuntimeError("PNG encoding failed")
    return buf.tobytes()
