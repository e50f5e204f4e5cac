"""What the Gaussians show beyond the labels, on Gaussians made up here: the surface noise of a capture."""

from __future__ import annotations

import numpy as np
import shapely

from sagebench.importers.boxes import OrientedBox
from sagebench.importers.interiorgs_evidence import surface_noise
from sagebench.importers.interiorgs_files import WallSegment
from sagebench.importers.interiorgs_structure import wall_pieces

WALL = WallSegment(np.array([0.0, 0.0]), np.array([4.0, 0.0]), thickness=0.2, height=2.5)
ROOM = shapely.box(0.0, 0.1, 4.0, 3.0)  # north of the wall
CHEST = OrientedBox(np.array([1.5, 0.45, 0.4]), np.eye(3), np.array([0.5, 0.3, 0.4]))  # against the wall


def _capture(noise: float, rng: np.random.Generator) -> np.ndarray:
    """Gaussians on both faces of WALL, captured 2 cm thicker than structure.json says, on the room's floor 3 mm
    high, and filling CHEST's box, all moved by `noise` (m, normal per axis)."""
    n = 6000
    x, z = rng.uniform(0.0, 4.0, n), rng.uniform(0.0, 2.5, n)
    faces = [np.stack([x, np.full(n, side * 0.12), z], axis=1) for side in (-1, 1)]
    floor = np.stack([rng.uniform(0.0, 4.0, n), rng.uniform(0.1, 3.0, n), np.full(n, 0.003)], axis=1)
    chest = CHEST.centre + rng.uniform(-1, 1, (4 * n, 3)) * CHEST.half
    points = np.concatenate([*faces, floor, chest])
    return points + rng.normal(0.0, noise, points.shape)


def test_surface_noise_is_the_scatter_about_where_the_capture_puts_walls_and_floor():
    """An offset between structure.json and the capture is not noise, nor is an object's inside; 5 mm of noise
    reads 5 mm (within 5 %; 5.5 mm with the chest's inside counted); no wall face or floor with Gaussians reads None."""
    rng = np.random.default_rng(0)
    pieces = wall_pieces(WALL, [])
    assert surface_noise(_capture(0.0, rng), pieces, ROOM, [CHEST], 0.02, 0.05) < 1e-9
    assert abs(surface_noise(_capture(0.005, rng), pieces, ROOM, [CHEST], 0.02, 0.05) - 0.005) <= 0.00025
    assert surface_noise(np.array([[2.0, 2.0, 1.5]]), pieces, ROOM, [CHEST], 0.02, 0.05) is None
