"""Colliders that would close floor the map leaves free: an object's parts reaching past its own agent-band
footprint onto free cells of build-scene's occupancy map (a wall's hull across its doorway).

The map blocks a cell that geometry touches, so a collider within the band tolerance of its object covers
free cells only within that tolerance (plus a cell of rasterisation) of blocked ones: only a covered cell
farther than that from every blocked cell counts, so the check flags parts that reach into open floor, not
the band error every method is allowed.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from sagebench.collider_export.convex import ConvexPart
from sagebench.collider_export.quality import band_polygons, rasterise
from sagebench.errors import ColliderError


@dataclass(frozen=True)
class FloorMap:
    """The occupancy build-scene wrote: [H, W] uint8 (1 blocked in the agent band, 0 free), rows = y."""

    occupancy: np.ndarray
    resolution: float  # m per cell
    origin: tuple[float, float]  # world (x, y) of cell (0, 0)'s lower-left corner


def covered_free_floor(parts: Sequence[ConvexPart], band: tuple[float, float], floor: FloorMap,
                       margin: float) -> np.ndarray | None:
    """World (x, y) of the free cell the parts (world frame) cover deepest inside open floor (the covered cell
    farthest from any blocked cell), when its centre is more than `margin` (m) plus a cell from every blocked
    cell's square; else None. `band`: (bottom, top) world z of the agent band."""
    polys = [q for p in parts for q in band_polygons(p.vertices[p.faces], *band)]
    if not polys:
        return None
    lo = np.asarray(floor.origin, dtype=np.float64)
    covered = rasterise(polys, lo, floor.resolution, floor.occupancy.shape)
    clearance = ndimage.distance_transform_edt(floor.occupancy == 0, sampling=floor.resolution)
    deep = np.where(covered, clearance - floor.resolution / 2, 0.0)  # centre to the nearest blocked square
    row, col = np.unravel_index(np.argmax(deep), deep.shape)
    if deep[row, col] <= margin + floor.resolution:
        return None
    return lo + (np.array([col, row]) + 0.5) * floor.resolution


def check_free_floor(placed: Sequence[tuple[str, np.ndarray, Sequence[ConvexPart], float, str]],
                     band: tuple[float, float], floor: FloorMap, tolerance_cm: float) -> None:
    """Raise a ColliderError naming the first object (name, 4x4 mesh -> world matrix, parts in the mesh frame,
    band error cm, why it is off) over the band tolerance whose parts cover free floor (covered_free_floor)."""
    for name, matrix, parts, error_cm, cause in placed:
        if error_cm <= tolerance_cm:
            continue
        world = [ConvexPart(p.vertices @ matrix[:3, :3].T + matrix[:3, 3], p.faces) for p in parts]
        spot = covered_free_floor(world, band, floor, tolerance_cm / 100)
        if spot is not None:
            raise ColliderError(f"{name}: colliders {error_cm:.1f} cm off in the agent band cover free floor at "
                                f"({spot[0]:.2f}, {spot[1]:.2f}) that the object leaves open (a doorway?): {cause}; "
                                "nothing was written")
