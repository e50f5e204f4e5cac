"""Connected regions of the navigable map and which rooms they join.

Regions are 8-connected (an agent on the grid may step diagonally), numbered 1.. in row-major order
of their first cell, so equal maps give equal numbers.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage

EIGHT = np.ones((3, 3), dtype=bool)


@dataclass(frozen=True)
class Reachability:
    labels: np.ndarray  # [H, W] int32, region id per navigable cell, 0 elsewhere
    region_cells: tuple[int, ...]  # cells per region, index = region id - 1
    room_regions: dict[str, tuple[int, ...]]  # room id -> the regions with navigable cells in the room
    reachable: dict[str, tuple[str, ...]]  # room id -> the other rooms sharing a region with it, sorted

    def all_rooms_connected(self) -> bool:
        """One region holds navigable cells of every room (vacuously true without rooms)."""
        rooms = list(self.room_regions)
        return all(set(self.reachable[r]) | {r} == set(rooms) and self.room_regions[r] for r in rooms)


def label_regions(navigable: np.ndarray) -> tuple[np.ndarray, int]:
    """[H, W] int32 region id per navigable cell (0 elsewhere) and the number of regions."""
    labels, count = ndimage.label(navigable.astype(bool), structure=EIGHT)
    return labels.astype(np.int32), int(count)


def reachability(navigable: np.ndarray, room_masks: dict[str, np.ndarray]) -> Reachability:
    """Regions of `navigable` ([H, W] bool) and, for each room (its [H, W] bool floor mask), the rooms
    reachable from it without leaving the navigable area."""
    labels, count = label_regions(navigable)
    cells = np.bincount(labels.ravel(), minlength=count + 1)[1:]
    room_regions = {
        room: tuple(int(v) for v in np.unique(labels[mask]) if v > 0) for room, mask in room_masks.items()
    }
    reachable = {
        room: tuple(sorted(o for o, regs in room_regions.items() if o != room and set(regs) & set(mine)))
        for room, mine in room_regions.items()
    }
    return Reachability(labels, tuple(int(c) for c in cells), room_regions, reachable)
