"""Plain reference for the grid A*: the same 8-connected, no-corner-cutting graph solved by scipy's Dijkstra.

Slow and obvious on purpose; tests and benchmarks check the fast A* against it.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import dijkstra


def grid_graph(navigable: np.ndarray) -> coo_matrix:
    """Sparse [H*W, H*W] adjacency in cells: 1 for a straight step, sqrt(2) for a diagonal with both sides free."""
    nav = np.asarray(navigable).astype(bool)
    h, w = nav.shape
    idx = np.arange(h * w).reshape(h, w)
    rows, cols, vals = [], [], []
    for dr, dc in ((-1, -1), (-1, 0), (-1, 1), (0, -1), (0, 1), (1, -1), (1, 0), (1, 1)):
        # every cell (r, c) whose neighbour (r + dr, c + dc) lies inside the grid
        src = (slice(max(-dr, 0), h - max(dr, 0)), slice(max(-dc, 0), w - max(dc, 0)))
        dst = (slice(max(dr, 0), h + min(dr, 0)), slice(max(dc, 0), w + min(dc, 0)))
        ok = nav[src] & nav[dst]
        if dr and dc:  # no corner cutting: both orthogonal neighbours (r + dr, c) and (r, c + dc) free
            ok &= nav[dst[0], src[1]] & nav[src[0], dst[1]]
        rows.append(idx[src][ok])
        cols.append(idx[dst][ok])
        vals.append(np.full(int(ok.sum()), math.sqrt(2.0) if dr and dc else 1.0))
    return coo_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(h * w, h * w))


def dijkstra_costs(navigable: np.ndarray, start: tuple[int, int], resolution: float) -> np.ndarray:
    """[H, W] float64 shortest-path cost in metres from `start` to every cell (inf where unreachable)."""
    nav = np.asarray(navigable).astype(bool)
    h, w = nav.shape
    if not nav[start]:
        return np.full((h, w), np.inf)
    dist = dijkstra(grid_graph(nav).tocsr(), directed=True, indices=start[0] * w + start[1])
    return dist.reshape(h, w) * resolution


def dijkstra_cost(navigable: np.ndarray, start: tuple[int, int], goal: tuple[int, int], resolution: float) -> float | None:
    """Shortest-path cost start -> goal in metres, or None when the goal is unreachable."""
    cost = float(dijkstra_costs(navigable, start, resolution)[goal])
    return None if math.isinf(cost) or not np.asarray(navigable)[goal] else cost


def path_cost(cells: np.ndarray, resolution: float) -> float:
    """Length in metres of a cell path [K, 2] (any step, straight or diagonal, measured as a segment)."""
    d = np.diff(np.asarray(cells, dtype=np.float64), axis=0)
    return float(np.hypot(d[:, 0], d[:, 1]).sum() * resolution)
