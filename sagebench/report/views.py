"""The start and goal views of each trajectory: the scene's Gaussians rendered (stages/render.py) at thumbnail
size from the agent's camera where it starts, facing its first heading, and at the end of the reference path,
facing the way it arrives."""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from pathlib import Path

from sagebench.settings.render import RenderConfig
from sagebench.stages.render import jpeg_bytes, render_views

Pose = tuple[float, float, float]  # x, y, yaw
CHUNK = 64  # views rendered at once: the frames of a chunk are in memory together


def start_and_goal(row: dict) -> tuple[Pose, Pose]:
    """The two view poses of an episode row."""
    x, y = row["start_position"][:2]
    gx, gy, _, gyaw = row["reference_path"][-1]
    return (float(x), float(y), float(row["start_yaw"])), (float(gx), float(gy), float(gyaw))


def render_thumbnails(run_dir: Path, scene_id: str, poses: Mapping[str, Pose],
                      config: RenderConfig) -> Iterator[tuple[str, bytes]]:
    """(key, JPEG bytes) of the view from each pose, in the order given."""
    keys = list(poses)
    for i in range(0, len(keys), CHUNK):
        chunk = keys[i:i + CHUNK]
        frames = render_views(run_dir, scene_id, [poses[k] for k in chunk], config)
        yield from ((k, jpeg_bytes(f.rgb)) for k, f in zip(chunk, frames))
