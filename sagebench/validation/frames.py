"""validate's spot checks: the agent's view rendered from the Gaussians at the start, middle and goal of a few
replays, its depth compared with the colliders' (appearance against physics), and the frames as PNGs for people."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import cv2
import mujoco
import numpy as np

from sagebench import ui
from sagebench.episodes.load import Trajectory
from sagebench.episodes.preview import png_bytes
from sagebench.replay.physics import AGENT_BODY, ReplayModel, ReplayRecord
from sagebench.run_layout import CONTACT_SHEET, FRAMES
from sagebench.settings.validate import ValidateConfig

if TYPE_CHECKING:
    from sagebench.render.gaussians import Gaussians

FRAME_POINTS = ("start", "middle", "goal")
# the images of each spot-check frame; instance ids from the CPU renderer where the backend draws none
VIEW_IMAGES = ("rgb", "depth", "alpha", "instance")


@dataclass(frozen=True)
class FrameCheck:
    file: str
    trajectory_id: str
    point: str  # start / middle / goal
    median_abs_diff: float  # m; NaN when no pixel could be compared
    compared: int
    sampled: int
    problem: str | None  # why the frame fails alignment (replay.alignment.frame_problem), None when it passes


def pick_frames(n: int, config: ValidateConfig) -> list[int]:
    """The trajectories (indices of `n`) that get spot-check frames: `frames_per_scene` of them, seeded."""
    k = min(n, config.frames_per_scene)
    return sorted(np.random.default_rng(config.seed).choice(n, size=k, replace=False).tolist()) if k else []


def spot_checks(gaussians: Gaussians, rm: ReplayModel, picks: list[tuple[Trajectory, ReplayRecord]],
                config: ValidateConfig) -> tuple[list[FrameCheck], dict[str, bytes]]:
    """Render start/middle/goal of each picked replay and compare its depth with the colliders; the checks and
    the PNGs (path under frames/ -> bytes: each view, its instance ids, and the contact sheet)."""
    if not picks:
        return [], {}
    from sagebench.replay.alignment import collider_depth, compare_depth, frame_problem, pixel_grid
    from sagebench.render.backends import CpuRenderer, open_renderer
    from sagebench.render.camera import agent_camera

    renderer = open_renderer(gaussians, config.renderer, needs=("rgb", "depth", "alpha"))
    data = mujoco.MjData(rm.model)
    mujoco.mj_kinematics(rm.model, data)
    agent_body = rm.model.body(AGENT_BODY).id
    checks, rows, pngs = [], [], {}
    for traj, rec in ui.track(picks, "spot-check frames"):
        tiles = []
        for point, k in zip(FRAME_POINTS, (0, len(rec.poses) // 2, len(rec.poses) - 1)):
            x, y, _, yaw = rec.poses[k]
            cam = agent_camera(x, y, yaw, floor_z=rm.floor_z, camera_height=config.camera.height,
                               hfov_deg=config.camera.hfov_deg, width=config.frame_width, height=config.frame_height)
            view = renderer.observe([cam], [img for img in VIEW_IMAGES if img in renderer.draws])
            if "instance" not in view:
                view |= CpuRenderer(gaussians).observe([cam], ("instance",))
            grid = pixel_grid(cam, config.ray_stride)
            a = compare_depth(view["depth"][0], view["alpha"][0], grid,
                              collider_depth(rm.model, data, cam, grid, bodyexclude=agent_body),
                              min_alpha=config.min_alpha)
            rgb, ids = view["rgb"][0], _id_colours(view["instance"][0])
            name = f"{traj.trajectory_id}_{point}"
            pngs[f"{name}.png"] = png_bytes(rgb)
            pngs[f"{name}_ids.png"] = png_bytes(ids)
            problem = frame_problem(a, tolerance=config.depth_tolerance, min_fraction=config.min_compared_fraction)
            checks.append(FrameCheck(f"{FRAMES}/{name}.png", traj.trajectory_id, point, a.median_abs_diff, a.compared,
                                     a.sampled, problem))
            tiles += [_label(rgb, f"{point}  d={a.median_abs_diff:.3f} m"), _label(ids, traj.trajectory_id)]
        rows.append(np.hstack(tiles))
    pngs[CONTACT_SHEET] = png_bytes(np.vstack(rows))
    return checks, pngs


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


