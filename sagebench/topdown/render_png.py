"""topdown.png for people: categories coloured with a legend, outlines, dark walls, doors by state,
the navigable floor tinted (in its own colour where it lies outside the main region: floor an agent starting in
the main region cannot reach), and a scale bar. North (+y) is up; objects that do not block are faded."""

from __future__ import annotations

import colorsys
from typing import TYPE_CHECKING

import cv2
import numpy as np

if TYPE_CHECKING:
    from sagebench.topdown.builder import Topdown

RGB = tuple[int, int, int]
BACKGROUND: RGB = (250, 250, 250)
FLOOR: RGB = (222, 222, 218)
WALL: RGB = (45, 45, 50)
WINDOW: RGB = (150, 190, 215)
NAVIGABLE: RGB = (120, 200, 150)
UNREACHABLE: RGB = (200, 90, 190)  # navigable, but outside the main region
OUTLINE: RGB = (70, 70, 70)
DOOR: dict[str, RGB] = {"open": (40, 160, 60), "ajar": (235, 150, 30), "closed": (200, 40, 40)}
TINT = 0.45  # weight of the navigable colour over the floor
TARGET_PX = 1000  # the map's longer side, roughly
LEGEND_W = 230
MAP_TOP = 30  # the title strip above the map
FONT = cv2.FONT_HERSHEY_SIMPLEX


def category_colour(index: int) -> RGB:
    """A distinct colour per category index (golden-ratio hue steps), the same in every map."""
    h = (index * 0.618033988749895) % 1.0
    r, g, b = colorsys.hsv_to_rgb(h, 0.55, 0.85)
    return (int(r * 255), int(g * 255), int(b * 255))


def render_topdown(td: Topdown) -> bytes:
    """PNG bytes of the maps build-scene computed."""
    sem = td.semantic
    h, w = td.grid.shape
    scale = map_scale(h, w)

    # colour per instance id, then per cell
    n_ids = int(max(i.instance_id for i in sem.instances)) + 1
    lut = np.tile(np.array(BACKGROUND, np.uint8), (n_ids, 1))
    legend: dict[str, RGB] = {}
    for inst in sem.instances:
        if inst.kind == "floor":
            colour = FLOOR
        elif inst.kind == "wall":
            colour = WALL
        elif inst.kind == "window":
            colour = WINDOW
        elif inst.kind == "door":
            colour = DOOR[inst.door_state or "closed"]
        elif inst.kind == "ceiling":
            continue
        else:
            colour = category_colour(inst.category_id)
            legend.setdefault(inst.category, colour)
            if not inst.blocks:  # above or below the agent's band (a ceiling lamp, a rug): drawn faded
                colour = tuple(int(round((a + b) / 2)) for a, b in zip(colour, FLOOR))
        lut[inst.instance_id] = colour
    img = lut[td.instance].astype(np.float32)
    floor_ids = np.array([i.instance_id for i in sem.instances if i.kind == "floor"], dtype=np.int64)
    on_floor = (td.instance == 0) | np.isin(td.instance, floor_ids)
    tint = np.where((td.region == sem.main_region)[..., None], np.float32(NAVIGABLE), np.float32(UNREACHABLE))
    img = np.where((td.navigable > 0)[..., None], (1 - TINT) * img + TINT * tint, img).astype(np.uint8)

    big = np.repeat(np.repeat(img, scale, axis=0), scale, axis=1)
    ids = np.repeat(np.repeat(np.where(on_floor, 0, td.instance), scale, axis=0), scale, axis=1)
    edge = np.zeros(ids.shape, dtype=bool)
    edge[:, :-1] |= ids[:, :-1] != ids[:, 1:]
    edge[:-1, :] |= ids[:-1, :] != ids[1:, :]
    big[edge] = OUTLINE
    big = np.ascontiguousarray(big[::-1])  # row 0 is the lowest y: put it at the bottom

    _scale_bar(big, td.grid.resolution / scale)
    items = [("navigable", NAVIGABLE), ("navigable, unreachable", UNREACHABLE), ("wall", WALL), ("window", WINDOW)]
    items += [(f"door ({s})", c) for s, c in DOOR.items()]
    items += sorted(legend.items())
    panel_h = max(big.shape[0], 40 + 20 * len(items))
    canvas = np.full((panel_h + MAP_TOP, big.shape[1] + LEGEND_W, 3), 255, np.uint8)
    canvas[MAP_TOP : MAP_TOP + big.shape[0], : big.shape[1]] = big
    cv2.putText(canvas, f"{sem.scene_id}  {w}x{h} cells @ {td.grid.resolution:g} m", (6, 20), FONT, 0.5,
                (0, 0, 0), 1, cv2.LINE_AA)
    x0 = big.shape[1] + 12
    for k, (name, colour) in enumerate(items):
        y = 44 + 20 * k
        cv2.rectangle(canvas, (x0, y - 11), (x0 + 14, y + 3), colour, -1)
        cv2.rectangle(canvas, (x0, y - 11), (x0 + 14, y + 3), OUTLINE, 1)
        cv2.putText(canvas, name, (x0 + 22, y), FONT, 0.45, (0, 0, 0), 1, cv2.LINE_AA)
    ok, data = cv2.imencode(".png", cv2.cvtColor(canvas, cv2.COLOR_RGB2BGR))
    if not ok:
        raise RuntimeError("PNG encoding failed")
    return data.tobytes()


def map_scale(h: int, w: int) -> int:
    """Pixels per cell of topdown.png's map for an [H, W] grid."""
    return int(np.clip(round(TARGET_PX / max(h, w)), 2, 8))


def map_pixels(xy: np.ndarray, h: int, scale: int, resolution: float, origin: tuple[float, float],
               top: int = 0) -> np.ndarray:
    """World (x, y) [N, 2] -> (column, row) [N, 2] in a picture of an [H, W] map drawn `scale` pixels per cell,
    north up, starting `top` pixels below the picture's top edge (topdown.png: MAP_TOP): where every picture of a
    map puts a point (paths.png, the episode pictures, the report's paths over topdown.png)."""
    xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
    col = (xy[:, 0] - origin[0]) / resolution
    row_from_top = h - (xy[:, 1] - origin[1]) / resolution
    return np.column_stack([col * scale, row_from_top * scale + top])


def _scale_bar(img: np.ndarray, metres_per_px: float) -> None:
    """A 1 m (or longer, for big maps) bar with its length written above, bottom-left."""
    length_m = 1.0
    while length_m / metres_per_px < img.shape[1] / 12:
        length_m *= 2
    px = int(round(length_m / metres_per_px))
    x0, y0 = 12, img.shape[0] - 14
    cv2.rectangle(img, (x0 - 4, y0 - 22), (x0 + px + 4, y0 + 8), (255, 255, 255), -1)
    cv2.rectangle(img, (x0, y0), (x0 + px, y0 + 4), (0, 0, 0), -1)
    cv2.putText(img, f"{length_m:g} m", (x0, y0 - 6), FONT, 0.45, (0, 0, 0), 1, cv2.LINE_AA)
