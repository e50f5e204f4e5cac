"""paths.png: a sample of reference paths drawn over the top-down map, for people to eyeball."""

from __future__ import annotations

from collections.abc import Sequence

import cv2
import numpy as np

_PALETTE = [(31, 119, 180), (255, 127, 14), (44, 160, 44), (214, 39, 40), (148, 103, 189),
            (140, 86, 75), (227, 119, 194), (23, 190, 207), (188, 189, 34), (127, 127, 127)]  # RGB


def render_paths(
    navigable: np.ndarray,  # [H, W] uint8
    occupancy: np.ndarray,  # [H, W] uint8, 1 = blocked
    paths: Sequence[np.ndarray],  # each [M, 2+] waypoints, world metres (x, y, ...)
    resolution: float,
    origin: tuple[float, float],
    *,
    max_size_px: int = 1000,
) -> bytes:
    """PNG bytes, north (+Y) up: blocked dark, free but too close to obstacles grey, navigable white.

    Each path is a coloured polyline from a green dot (start) to a red ring (goal).
    """
    h, w = navigable.shape
    scale = max(1, max_size_px // max(h, w))
    base = np.full((h, w, 3), 200, dtype=np.uint8)
    base[occupancy != 0] = 70
    base[navigable != 0] = 255
    img = np.ascontiguousarray(np.repeat(np.repeat(base[::-1], scale, axis=0), scale, axis=1))
    for i, wps in enumerate(paths):
        px = _pixels(np.asarray(wps)[:, :2], h, scale, resolution, origin)
        rgb = _PALETTE[i % len(_PALETTE)]
        cv2.polylines(img, [px], False, rgb, thickness=max(1, scale // 2), lineType=cv2.LINE_AA)
        cv2.circle(img, tuple(int(v) for v in px[0]), 2 * scale, (0, 170, 0), -1, lineType=cv2.LINE_AA)
        cv2.circle(img, tuple(int(v) for v in px[-1]), 2 * scale, (200, 0, 0), max(1, scale // 2), lineType=cv2.LINE_AA)
    ok, png = cv2.imencode(".png", cv2.cvtColor(img, cv2.COLOR_RGB2BGR))
    if not ok:
        raise RuntimeError("PNG encoding failed")
    return png.tobytes()


def _pixels(xy: np.ndarray, h: int, scale: int, resolution: float, origin: tuple[float, float]) -> np.ndarray:
    col = (xy[:, 0] - origin[0]) / resolution
    row_from_top = h - (xy[:, 1] - origin[1]) / resolution
    return np.round(np.column_stack([col, row_from_top]) * scale).astype(np.int32)
