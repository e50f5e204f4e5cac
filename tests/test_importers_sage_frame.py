"""SAGE-3D's 3D frame of an InteriorGS scene: its tools mirror about mask bounds rounded to 2 decimals (format2)."""

from __future__ import annotations

import numpy as np
import pytest

from sagebench.gvln.frame import to_sage_xy
from sagebench.importers.interiorgs_files import FREE, UNKNOWN, Label, OccupancyMap
from sagebench.importers.sage_frame import sage_offset
from tests.sage_benchmark import sage_semantic_map, sage_to_2d

ORIGIN, SCALE, SHAPE = (0.013, -0.006), 0.05, (30, 40)  # cell centres at 0.038, 0.019: 3 decimals


def _ring() -> tuple[np.ndarray, list[Label]]:
    values = np.full(SHAPE, FREE, np.uint8)
    values[[0, -1], :] = values[:, [0, -1]] = UNKNOWN  # walls and outside reach the map's edges
    return values, []


def _inner() -> tuple[np.ndarray, list[Label]]:
    values = np.full(SHAPE, FREE, np.uint8)
    values[10:13, 5:8] = UNKNOWN  # a wall block
    values[0, 0:4] = 0  # 4 occupied cells: under SAGE's 5, no "unable area"
    square = [(1.2, 0.5), (1.5, 0.5), (1.5, 0.8), (1.2, 0.8)]
    corners = np.array([(x, y, z) for z in (0.0, 1.0) for x, y in square])
    return values, [Label(0, "000001", "sofa", corners)]


# (ring) x centres 0.038 .. 1.988 -> 0.04 + 1.99 = 2.03 against 2 * 0.013 + 40 * 0.05 = 2.026; y 0.019 .. 1.469 ->
# 0.02 + 1.47 = 1.49 against 1.488. (inner) columns 5..7 (wall) and 24..29 (sofa: centres 1.238 .. 1.488), turned:
# 10..34, centres 0.538, 1.738 -> 0.54 + 1.74 = 2.28; rows 10..15 turned 14..19: 0.719, 0.969 -> 0.72 + 0.97 = 1.69.
@pytest.mark.parametrize(("make", "expected"), [(_ring, (-0.004, -0.002)), (_inner, (2.026 - 2.28, 1.488 - 1.69))])
def test_a_world_point_lands_where_sage_s_rounded_bounds_put_it(make, expected):
    values, labels = make()
    offset = sage_offset(OccupancyMap(values, SCALE, ORIGIN), labels)
    assert offset == pytest.approx(expected, abs=1e-9)
    # SAGE's evaluator takes the point back to its 2D map, where the world is turned about the grid's centre
    png = values[:, ::-1]  # occupancy.png: the grid turned by 180 degrees, as SAGE reads it (flipped up-down)
    labels_json = [{"label": lab.label, "bounding_box": [dict(zip("xyz", map(float, c))) for c in lab.corners]}
                   for lab in labels]
    smap = sage_semantic_map(labels_json, png, ORIGIN, SCALE)
    world = np.array([0.61, 0.93])
    centre_sum = 2 * np.asarray(ORIGIN) + np.array(SHAPE[::-1]) * SCALE
    assert sage_to_2d(list(to_sage_xy(world, offset)), smap) == pytest.approx(centre_sum - world, abs=1e-9)
