"""Optimal 8-connected grid A* (numba): octile heuristic, no corner cutting, indexed binary heap.

The graph: a cell is a node when `navigable[r, c]` is non-zero; a straight step costs 1 cell, a
diagonal step sqrt(2) cells and needs both orthogonal neighbours navigable (the agent never cuts
a blocked corner). Costs are returned in metres (cells x resolution). The octile heuristic is
consistent on this graph, so the first time the goal is popped its cost is optimal; ties on f are
broken towards larger g, which walks straight at the goal across open floor. Costs are kept as
int64 fixed point (a straight step = 2**40) so that equal-cost paths tie exactly: float sums of
sqrt(2) in different orders differ in the last bit and would make A* flood every tied cell.

A `Workspace` keeps the per-cell arrays between queries; a generation stamp marks which entries
belong to the current query, so nothing is cleared and a query costs only the cells it touches.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np

STRAIGHT = 1 << 40  # fixed-point cost of a straight step
DIAGONAL = round(math.sqrt(2.0) * STRAIGHT)  # fixed-point cost of a diagonal step
# neighbour offsets (dr, dc): the four straight moves first, then the four diagonals
_DR = np.array([-1, 1, 0, 0, -1, -1, 1, 1], dtype=np.int64)
_DC = np.array([0, 0, -1, 1, -1, 1, -1, 1], dtype=np.int64)


@dataclass(frozen=True)
class GridPath:
    """A shortest path: `cost` in metres, `cells` [K, 2] int32 (row, col) from start to goal inclusive."""

    cost: float
    cells: np.ndarray


class Workspace:
    """Per-cell scratch arrays for one grid shape, reused across queries (not thread-safe)."""

    def __init__(self, shape: tuple[int, int]):
        n = int(shape[0]) * int(shape[1])
        self.shape = (int(shape[0]), int(shape[1]))
        self.g = np.empty(n, dtype=np.int64)  # cost from start, fixed point
        self.f = np.empty(n, dtype=np.int64)  # g + heuristic
        self.parent = np.empty(n, dtype=np.int64)
        self.pos = np.empty(n, dtype=np.int64)  # heap position; -1 once closed
        self.stamp = np.zeros(n, dtype=np.int64)  # == generation when the entries above are valid
        self.heap = np.empty(n, dtype=np.int64)
        self.generation = 0


def astar(
    navigable: np.ndarray,  # [H, W] uint8 or bool, non-zero = the agent may stand here
    start: tuple[int, int],  # (row, col)
    goal: tuple[int, int],  # (row, col)
    resolution: float,  # metres per cell
    workspace: Workspace | None = None,
) -> GridPath | None:
    """Shortest 8-connected path from `start` to `goal`, or None when none exists.

    None also when start or goal is outside the grid or not navigable.
    """
    nav = _as_u8(navigable)
    h, w = nav.shape
    (sr, sc), (gr, gc) = (int(start[0]), int(start[1])), (int(goal[0]), int(goal[1]))
    if not (0 <= sr < h and 0 <= sc < w and 0 <= gr < h and 0 <= gc < w):
        return None
    if workspace is None or workspace.shape != (h, w):
        workspace = Workspace((h, w))
    workspace.generation += 1
    ws = workspace
    n_path = _astar_kernel(nav, sr * w + sc, gr * w + gc, ws.g, ws.f, ws.parent, ws.pos, ws.stamp, ws.heap,
                           ws.generation)
    if n_path == 0:
        return None
    flat = _trace(ws.parent, gr * w + gc, n_path)
    cells = np.empty((n_path, 2), dtype=np.int32)
    cells[:, 0] = flat // w
    cells[:, 1] = flat % w
    return GridPath(cost=float(ws.g[gr * w + gc]) / STRAIGHT * resolution, cells=cells)


def _as_u8(navigable: np.ndarray) -> np.ndarray:
    if navigable.ndim != 2:
        raise ValueError(f"navigable must be a [H, W] array, got shape {navigable.shape}")
    return np.ascontiguousarray(navigable, dtype=np.uint8)


@numba.njit(cache=True, inline="always")
def _less(a: int, b: int, f: np.ndarray, g: np.ndarray) -> bool:
    fa, fb = f[a], f[b]
    return fa < fb or (fa == fb and g[a] > g[b])


@numba.njit(cache=True)
def _sift_up(heap, pos, i, f, g):
    node = heap[i]
    while i > 0:
        up = (i - 1) >> 1
        other = heap[up]
        if not _less(node, other, f, g):
            break
        heap[i] = other
        pos[other] = i
        i = up
    heap[i] = node
    pos[node] = i


@numba.njit(cache=True)
def _sift_down(heap, pos, size, i, f, g):
    node = heap[i]
    while True:
        child = 2 * i + 1
        if child >= size:
            break
        right = child + 1
        if right < size and _less(heap[right], heap[child], f, g):
            child = right
        other = heap[child]
        if not _less(other, node, f, g):
            break
        heap[i] = other
        pos[other] = i
        i = child
    heap[i] = node
    pos[node] = i


@numba.njit(cache=True)
def _octile(r, c, gr, gc):
    dr = abs(r - gr)
    dc = abs(c - gc)
    lo = min(dr, dc)
    return (dr + dc - 2 * lo) * STRAIGHT + DIAGONAL * lo


@numba.njit(cache=True)
def _astar_kernel(nav, start, goal, g, f, parent, pos, stamp, heap, gen):
    """Returns the number of cells on the path (0: no path); g/parent then hold the search tree."""
    h, w = nav.shape
    flat = nav.ravel()
    if flat[start] == 0 or flat[goal] == 0:
        return 0
    gr, gc = goal // w, goal % w
    stamp[start] = gen
    g[start] = 0
    f[start] = _octile(start // w, start % w, gr, gc)
    parent[start] = -1
    heap[0] = start
    pos[start] = 0
    size = 1
    while size > 0:
        cur = heap[0]
        size -= 1
        if size > 0:
            heap[0] = heap[size]
            pos[heap[0]] = 0
            _sift_down(heap, pos, size, 0, f, g)
        pos[cur] = -1  # closed
        if cur == goal:
            n = 1
            k = cur
            while parent[k] != -1:
                k = parent[k]
                n += 1
            return n
        r, c = cur // w, cur % w
        gcur = g[cur]
        for k in range(8):
            dr, dc = _DR[k], _DC[k]
            nr, nc = r + dr, c + dc
            if nr < 0 or nr >= h or nc < 0 or nc >= w:
                continue
            nb = nr * w + nc
            if flat[nb] == 0:
                continue
            if k >= 4:
                if flat[r * w + nc] == 0 or flat[nr * w + c] == 0:
                    continue
                step = DIAGONAL
            else:
                step = STRAIGHT
            cand = gcur + step
            if stamp[nb] == gen:
                if pos[nb] < 0 or cand >= g[nb]:
                    continue
                g[nb] = cand
                f[nb] = cand + _octile(nr, nc, gr, gc)
                parent[nb] = cur
                _sift_up(heap, pos, pos[nb], f, g)
            else:
                stamp[nb] = gen
                g[nb] = cand
                f[nb] = cand + _octile(nr, nc, gr, gc)
                parent[nb] = cur
                heap[size] = nb
                pos[nb] = size
                size += 1
                _sift_up(heap, pos, size - 1, f, g)
    return 0


@numba.njit(cache=True)
def _trace(parent, goal, n):
    out = np.empty(n, dtype=np.int64)
    k = goal
    for i in range(n - 1, -1, -1):
        out[i] = k
        k = parent[k]
    return out
