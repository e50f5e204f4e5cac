"""The shipped occupancy.png against sagebench's own height-band occupancy of the imported geometry.

Both are read on the shipped map's own grid: a cell is free for sagebench when it lies on a room's floor and
nothing of the imported geometry (walls, doors, windows, objects) stands in the agent's height band over it,
and free for InteriorGS where its pixel is 255. The IoU of the two free sets says how far the imported
geometry agrees with what the dataset's authors saw; the picture shows where they differ, and in orange the
cells blocked by obstacles no label explains (importers/interiorgs_evidence.py).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
import shapely
import trimesh

from sagebench.importers.interiorgs_files import OccupancyMap
from sagebench.topdown.footprints import mesh_parts
from sagebench.topdown.occupancy import band_occupancy
from sagebench.topdown.raster import Grid, polygon_mask

BOTH, OURS_ONLY, THEIRS_ONLY, NEITHER = (235, 235, 235), (220, 60, 60), (60, 90, 220), (70, 70, 70)
UNLABELLED_RGB = (240, 150, 30)


@dataclass(frozen=True)
class OccupancyAgreement:
    iou: float  # of the free cells
    free_ours: int  # cells
    free_theirs: int
    picture: bytes  # PNG, north up: grey both free, red free only for sagebench, blue only in occupancy.png


def band_blocked(shipped: OccupancyMap, blockers: list[trimesh.Trimesh], band: tuple[float, float]) -> np.ndarray:
    """[H, W] the cells of the shipped map's grid that `blockers` (world meshes) stand on in the height `band`."""
    h, w = shipped.values.shape
    parts = [mesh_parts(m) for m in blockers]
    if not parts:
        return np.zeros((h, w), dtype=bool)
    tris = np.concatenate([t for t, _ in parts])
    offsets = np.cumsum([0] + [int(p.max()) + 1 if len(p) else 0 for _, p in parts])[:-1]
    part = np.concatenate([p + o for (_, p), o in zip(parts, offsets)])
    return band_occupancy(tris, part, Grid(shipped.origin, shipped.scale, (h, w)), *band)


def compare_occupancy(shipped: OccupancyMap, blocked: np.ndarray, rooms: list[shapely.Polygon],
                      unlabelled: np.ndarray) -> OccupancyAgreement:
    """Free cells of the shipped map against ours over `rooms`: those no imported geometry blocks (`blocked`
    [H, W], `unlabelled` [H, W] the cells of obstacles no label explains, blocked too)."""
    h, w = shipped.values.shape
    grid = Grid(shipped.origin, shipped.scale, (h, w))
    blocked = blocked | unlabelled
    ours = polygon_mask(shapely.union_all(rooms), grid) & ~blocked
    theirs = shipped.free
    union = int((ours | theirs).sum())
    iou = float((ours & theirs).sum()) / union if union else 1.0
    rgb = np.empty((h, w, 3), dtype=np.uint8)
    rgb[:] = NEITHER
    rgb[ours & theirs] = BOTH
    rgb[ours & ~theirs] = OURS_ONLY
    rgb[~ours & theirs] = THEIRS_ONLY
    rgb[unlabelled] = UNLABELLED_RGB
    scale = max(1, 800 // max(h, w))
    big = np.repeat(np.repeat(rgb[::-1], scale, axis=0), scale, axis=1)  # row 0 is the lowest y: flip to north up
    ok, png = cv2.imencode(".png", cv2.cvtColor(np.ascontiguousarray(big), cv2.COLOR_RGB2BGR))
    return OccupancyAgreement(iou, int(ours.sum()), int(theirs.sum()), bytes(png))
