"""Oriented boxes given by 8 corners (InteriorGS's labels), and which box holds each point (the tightest one).

A box's corners may come in any order. From one corner, the nearest other corner is along its shortest edge
(any sum of perpendicular edges is longer than each of them); the nearest corner along a perpendicular is along
a second edge, and the one perpendicular to both along the third. The other four corners must then be sums of
those edges, within a tolerance.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

CORNER_TOLERANCE = 0.02  # a corner may lie this fraction of the box's diagonal off the box its edges span
MIN_EDGE_M = 1e-4  # an edge shorter than this makes a box of no volume
PERPENDICULAR_COS = 0.05  # edges of a box meet at 90 degrees within about 3 degrees


class BoxError(ValueError):
    """The corners do not make a box of some volume; the message says why (the caller names the file)."""


@dataclass(frozen=True)
class OrientedBox:
    """centre [3] m; axes [3, 3], one unit axis per row, right-handed, the most vertical last; half [3] m."""

    centre: np.ndarray
    axes: np.ndarray
    half: np.ndarray

    @property
    def volume(self) -> float:
        return float(8.0 * np.prod(self.half))

    def local(self, points: np.ndarray) -> np.ndarray:
        """[N, 3] world points -> coordinates along the box's axes, from its centre."""
        return (np.asarray(points, dtype=np.float64) - self.centre) @ self.axes.T

    def contains(self, points: np.ndarray, margin: float = 0.0) -> np.ndarray:
        """[N] bool: inside the box grown by `margin` m on every side (boundary included)."""
        return (np.abs(self.local(points)) <= self.half + margin).all(axis=1)

    def corners(self) -> np.ndarray:
        """[8, 3]: the bottom face's corners counter-clockwise seen from above, then the top face's in the same
        order (the order SAGE-3D reads, taking the first four as the footprint)."""
        signs = np.array([[-1, -1, -1], [1, -1, -1], [1, 1, -1], [-1, 1, -1],
                          [-1, -1, 1], [1, -1, 1], [1, 1, 1], [-1, 1, 1]], dtype=np.float64)
        return self.centre + (signs * self.half) @ self.axes

    def aabb(self, margin: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
        reach = np.abs(self.axes).T @ (self.half + margin)
        return self.centre - reach, self.centre + reach


def box_from_corners(corners: np.ndarray) -> OrientedBox:
    """The box whose corners are `corners` [8, 3] (any order); BoxError if they are not a box of some volume."""
    c = np.asarray(corners, dtype=np.float64)
    if c.shape != (8, 3) or not np.isfinite(c).all():
        raise BoxError(f"expected 8 finite corners, got an array of shape {c.shape}")
    vectors = c[1:] - c[0]
    d = np.linalg.norm(vectors, axis=1)
    diag = float(d.max())
    if d.min() < MIN_EDGE_M:
        raise BoxError(f"zero volume: two corners are {d.min():.2g} m apart")
    edges = [vectors[int(np.argmin(d))]]
    for _ in range(2):
        cos = np.abs(vectors @ np.array(edges).T) / (d[:, None] * np.linalg.norm(edges, axis=1)[None, :])
        perpendicular = np.flatnonzero((cos < PERPENDICULAR_COS).all(axis=1))
        if not len(perpendicular):
            raise BoxError("the corners are not those of a box (no three perpendicular edges)")
        edges.append(vectors[perpendicular[np.argmin(d[perpendicular])]])
    edges = np.array(edges)
    expected = c[0] + np.array([[i, j, k] for i in (0, 1) for j in (0, 1) for k in (0, 1)], dtype=np.float64) @ edges
    off = np.linalg.norm(c[:, None, :] - expected[None, :, :], axis=2)  # [8 given, 8 expected]
    if off.min(axis=1).max() > CORNER_TOLERANCE * diag or off.min(axis=0).max() > CORNER_TOLERANCE * diag:
        raise BoxError("the corners are not those of a box (the three edges from a corner do not span the others)")
    q, _ = np.linalg.qr(edges.T)  # orthonormal axes spanning the edges, in their order
    axes = q.T
    axes = axes[np.argsort(np.abs(axes[:, 2]), kind="stable")]  # the most vertical axis last
    if axes[2, 2] < 0:
        axes[2] = -axes[2]
    if np.linalg.det(axes) < 0:
        axes[0] = -axes[0]
    centre = c.mean(axis=0)
    half = np.abs((c - centre) @ axes.T).max(axis=0)
    if half.min() * 2 < MIN_EDGE_M:
        raise BoxError(f"zero volume: the box is {2 * half.min():.2g} m thin")
    return OrientedBox(centre, axes, half)


def box_owner(points: np.ndarray, boxes: list[OrientedBox], margin: float = 0.0) -> np.ndarray:
    """[N] int: for each point [N, 3], the index of the smallest box of `boxes` that holds it, -1 for none.

    Boxes are visited from the largest to the smallest volume, each overwriting the points it holds, so a
    point in nested boxes ends with the tightest. Each box only tests the points inside its x range: the points
    are sorted by x once, each coordinate in its own array, so that range is a slice, not a copy.
    """
    pts = np.asarray(points, dtype=np.float64)
    owner = np.full(len(pts), -1, dtype=np.int64)
    if not boxes or not len(pts):
        return owner
    order = np.argsort(pts[:, 0], kind="stable")
    xs, ys, zs = pts[order].T.copy()
    for b in sorted(range(len(boxes)), key=lambda i: -boxes[i].volume):
        lo, hi = boxes[b].aabb(margin)
        a, e = np.searchsorted(xs, lo[0], "left"), np.searchsorted(xs, hi[0], "right")
        y, z = ys[a:e], zs[a:e]
        near = a + np.flatnonzero((y >= lo[1]) & (y <= hi[1]) & (z >= lo[2]) & (z <= hi[2]))
        inside = boxes[b].contains(np.stack([xs[near], ys[near], zs[near]], axis=1), margin)
        owner[order[near[inside]]] = b
    return owner


def box_owner_reference(points: np.ndarray, boxes: list[OrientedBox], margin: float = 0.0) -> np.ndarray:
    """Plain version of `box_owner`: every point against every box, the smallest holding box wins."""
    owner = np.full(len(points), -1, dtype=np.int64)
    for i, p in enumerate(np.asarray(points, dtype=np.float64)):
        holding = [b for b, box in enumerate(boxes) if box.contains(p[None], margin)[0]]
        if holding:
            owner[i] = min(holding, key=lambda b: (boxes[b].volume, -b))
    return owner
