"""ImageNav's goal image: the PNG file an episode names (an imported episode's, run-relative), else the view rendered
from the goal pose (gen-trajectories' `render:x,y,yaw`, docs/tasks/imagenav.md). A file is what the agent is shown, so it must
be a PNG of the rgb observation's size: anything else is refused before the rollout writes a byte."""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np

from sagebench.episodes.episode import Episode
from sagebench.errors import DataError
from sagebench.input_files import read_input

RENDERED = "render:"  # goal_image's prefix for a goal view rendered on demand
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def goal_image_file(run_dir: Path, episode: Episode) -> Path | None:
    """The file an imagenav episode's goal_image names, relative to the run; None for a rendered goal (or another
    task)."""
    value = episode.goal_image
    if episode.task != "imagenav" or not value or value.startswith(RENDERED):
        return None
    return Path(run_dir) / value


def read_goal_image(path: Path, size: tuple[int, int], episode_id: str) -> np.ndarray:
    """[H, W, 3] uint8: the PNG at `path`; a DataError naming the file and the episode's goal_image unless it is a
    readable PNG of `size` (width, height: the rgb observation's)."""
    from PIL import Image  # only a file goal needs it (a GPU image has no Pillow; rendered goals do not)

    field = f"goal_image of episode {episode_id}"
    try:
        data = read_input(path)
    except DataError as err:
        raise DataError(err.detail, path=path, field=field) from None
    if not data.startswith(PNG_SIGNATURE):
        raise DataError("is not a PNG file", path=path, field=field)
    try:
        with Image.open(io.BytesIO(data)) as im:
            rgb = np.asarray(im.convert("RGB"))
    except (OSError, ValueError, Image.DecompressionBombError) as err:
        raise DataError(f"cannot decode the PNG: {err}", path=path, field=field) from None
    if (rgb.shape[1], rgb.shape[0]) != tuple(size):
        raise DataError(f"is {rgb.shape[1]}x{rgb.shape[0]} px; the rgb observation is {size[0]}x{size[1]}",
                        path=path, field=field)
    return rgb
