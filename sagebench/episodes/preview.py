"""paths.png: a sample of reference paths drawn over the top-down map, for people to eyeball; and that plain map
(blocked, free, navigable), which the episode pictures draw on too."""

from __future__ import annotations

from collections.abc import Sequence

import cv2
import numpy as np

from sagebench.topdown.render_png import map_pixels

_PALETTE = [(31, 119, 180), (255, 127, 14), (44, 160, 44), (214, 39, 40), (148, 103, 189),
            (140, 86, 75), (227, 119, 194), (23, 190, 207), (188, 189, 34), (127, 127, 127)]  # RGB
BLOCKED, FREE, NAVIGABLE = 70, 200, 255  # grey levels of the plain map
START, GOAL = (0, 170, 0), (200, 0, 0)  # RGB


def plain_map(navigable: np.ndarray, occupancy: np.ndarray, scale: int) -> np.ndarray:
    """[H * scale, W * scale, 3] uint8 RGB, north (+Y) up: blocked dark, free but too close to obstacles grey,
    navigable white."""
    base = np.full((*navigable.shape, 3), FREE, dtype=np.uint8)
    base[occupancy != 0] = BLOCKED
    base[navigable != 0] = NAVIGABLE
    return np.ascontiguousarray(np.repeat(np.repeat(base[::-1], scale, axis=0), scale, axis=1))


def png_bytes(rgb: np.ndarray, level: int | None = None) -> bytes:
    """PNG bytes of an RGB image (the same image, the same bytes); `level` 0-9 the zlib compression (None:
    OpenCV's default, fast but large)."""
    params = [] if level is None else [cv2.IMWRITE_PNG_COMPRESSION, level]
    ok, png = cv2.imencode(".png", np.ascontiguousarray(rgb[:, :, ::-1]), params)
    if not ok:
        raise RuntimeError("PNG encoding failed")
    return png.tobytes()


def render_paths(
    navigable: np.ndarray,  # [H, W] uint8
    occupancy: np.ndarray,  # [H, W] uint8, 1 = blocked
    paths: Sequence[np.ndarray],  # each [M, 2+] waypoints, world metres (x, y, ...)
    resolution: float,
    origin: tuple[float, float],
    *,
    max_size_px: int = 1000,
) -> bytes:
    """PNG bytes of the plain map with each path as a coloured polyline from a green dot (start) to a red ring
    (goal)."""
    h, w = navigable.shape
    scale = max(1, max_size_px // max(h, w))
    img = plain_map(navigable, occupancy, scale)
    for i, wps in enumerate(paths):
        px = np.round(map_pixels(np.asarray(wps)[:, :2], h, scale, resolution, origin)).astype(np.int32)
        rgb = _PALETTE[i % len(_PALETTE)]
        cv2.polylines(img, [px], False, rgb, thickness=max(1, scale // 2), lineType=cv2.LINE_AA)
        cv2.circle(img, tuple(int(v) for v in px[0]), 2 * scale, START, -1, lineType=cv2.LINE_AA)
        cv2.circle(img, tuple(int(v) for v in px[-1]), 2 * scale, GOAL, max(1, scale // 2), lineType=cv2.LINE_AA)
    return png_bytes(img)
