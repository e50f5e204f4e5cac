"""Connected regions of the navigable map, the main one, and which rooms an agent can reach.

Regions are the connected parts of the planner's graph: 8-connected steps that never cut a blocked corner
(`sagebench/astar`), so two cells touching only diagonally are not joined; as components these are the
4-connected ones. They are numbered 1.. in row-major order of their first cell, so equal maps give equal
numbers. The main region is the largest (the lowest id among equals).

A room is reachable when more than half (`REACHABLE_SHARE`) of its navigable cells lie in the main region:
an office that the main region touches with one cell through an ajar door, the rest of its floor cut off,
is not. Rooms reach each other when the same region holds more than half of each one's navigable cells.
`room_reachability` is build-scene's step: the regions of the navigable map and the reach of the scene's rooms.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import shapely
from scipy import ndimage

from sagebench.topdown.raster import Grid, polygon_mask

if TYPE_CHECKING:
    from sagebench.scene.model import Room

REACHABLE_SHARE = 0.5  # a room is reachable when strictly more than this share of its navigable cells is in the main region


@dataclass(frozen=True)
class Reachability:
    labels: np.ndarray  # [H, W] int32, region id per navigable cell, 0 elsewhere
    region_cells: tuple[int, ...]  # cells per region, index = region id - 1
    main_region: int  # id of the largest region; 0 when nothing is navigable
    room_regions: dict[str, tuple[int, ...]]  # room id -> the regions with navigable cells in the room
    room_cells: dict[str, int]  # room id -> its navigable cells
    room_main_cells: dict[str, int]  # room id -> its navigable cells in the main region
    home: dict[str, int]  # room id -> the region holding more than half its navigable cells, 0 when none does

    def room_reachable(self, room: str) -> bool:
        """More than `REACHABLE_SHARE` of the room's navigable cells lie in the main region."""
        return self.room_main_cells[room] > REACHABLE_SHARE * self.room_cells[room]

    def unreachable_cells(self, room: str) -> int:
        """The room's navigable cells outside the main region."""
        return self.room_cells[room] - self.room_main_cells[room]

    def reachable_from(self, room: str) -> tuple[str, ...]:
        """The other rooms whose home region is this room's (sorted; none when the room has no home region)."""
        mine = self.home[room]
        return tuple(sorted(o for o, k in self.home.items() if o != room and mine and k == mine))

    def all_rooms_connected(self) -> bool:
        """Every room is reachable (vacuously true without rooms)."""
        return all(self.room_reachable(r) for r in self.room_cells)


def label_regions(navigable: np.ndarray) -> tuple[np.ndarray, int]:
    """[H, W] int32 region id per navigable cell (0 elsewhere) and the number of regions."""
    labels, count = ndimage.label(navigable.astype(bool))  # 4-connected = 8-connected without corner cutting
    return labels.astype(np.int32), int(count)


def reachability(navigable: np.ndarray, room_masks: dict[str, np.ndarray]) -> Reachability:
    """Regions of `navigable` ([H, W] bool) and, for each room (its [H, W] bool floor mask), how much of its
    navigable floor lies in which region."""
    labels, count = label_regions(navigable)
    cells = np.bincount(labels.ravel(), minlength=count + 1)[1:]
    main = int(np.argmax(cells)) + 1 if count else 0
    per_room = {room: np.bincount(labels[mask], minlength=count + 1) for room, mask in room_masks.items()}
    room_cells = {room: int(n[1:].sum()) for room, n in per_room.items()}
    biggest = {room: int(np.argmax(n[1:])) + 1 if count else 0 for room, n in per_room.items()}
    home = {room: k if k and per_room[room][k] > REACHABLE_SHARE * room_cells[room] else 0
            for room, k in biggest.items()}
    return Reachability(
        labels=labels,
        region_cells=tuple(int(c) for c in cells),
        main_region=main,
        room_regions={room: tuple(int(k) for k in np.nonzero(n[1:])[0] + 1) for room, n in per_room.items()},
        room_cells=room_cells,
        room_main_cells={room: int(n[main]) if main else 0 for room, n in per_room.items()},
        home=home,
    )


def room_reachability(navigable: np.ndarray, rooms: Sequence[Room], grid: Grid) -> Reachability:
    """`reachability` of the navigable map ([H, W] on `grid`, nonzero = navigable, passages included) for the
    rooms: each room's floor is the cells whose centre lies in its polygon (world xy, m)."""
    return reachability(navigable, {r.id: polygon_mask(shapely.Polygon(r.polygon), grid) for r in rooms})
