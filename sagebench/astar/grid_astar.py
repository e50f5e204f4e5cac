"""Optimal 8-connected grid A* (numba): octile heuristic, no corner cutting, binary heap, jump points.

The graph: a cell is a node when `navigable[r, c]` is non-zero; a straight step costs 1 cell, a
diagonal step sqrt(2) cells and needs both orthogonal neighbours navigable (the agent never cuts
a blocked corner). Costs are returned in metres (cells x resolution).

The search is A* with jump-point pruning (Harabor & Grastien's JPS, in its no-corner-cutting
form): instead of pushing all eight neighbours, a cell pushes only the next "jump point" along each
direction that an optimal path could need, found by scanning straight or diagonal runs of free
cells. This changes how many cells enter the heap, not the answer: the octile heuristic is
consistent, so the goal's cost is optimal, and the run between two jump points is filled back in,
so the returned path lists every cell. Ties on f go to larger g. Costs are int64 fixed point (a
straight step = 2**40) so that equal-cost paths tie exactly: float sums of sqrt(2) taken in
different orders differ in the last bit.

A `Workspace` keeps the per-cell arrays between queries; a generation stamp marks which entries
belong to the current query, so nothing is cleared and a query costs only the cells it touches.
The open list is a binary heap of (f, g, cell) entries with lazy deletion.
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
        self.parent = np.empty(n, dtype=np.int32)
        self.stamp = np.zeros(n, dtype=np.int32)  # generation: reached in this query; generation + 1: closed
        self.generation = 0
        self._heap(n + 1024)

    def _heap(self, capacity: int) -> None:
        # heap entries hold their keys inline (f, g) so sifting never reads the per-cell arrays
        self.heap_f = np.empty(capacity, dtype=np.int64)
        self.heap_g = np.empty(capacity, dtype=np.int64)
        self.heap_node = np.empty(capacity, dtype=np.int32)

    def next_generation(self) -> int:
        if self.generation > 2**30:
            self.stamp[:] = 0
            self.generation = 0
        self.generation += 2
        return self.generation


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
    ws = workspace
    while True:
        n_path = _astar_kernel(nav, sr * w + sc, gr * w + gc, ws.g, ws.parent, ws.stamp, ws.next_generation(),
                               ws.heap_f, ws.heap_g, ws.heap_node)
        if n_path >= 0:
            break
        ws._heap(2 * len(ws.heap_f))  # more stale heap entries than room: grow and search again
    if n_path == 0:
        return None
    flat = _trace(ws.parent, gr * w + gc, n_path, w)
    cells = np.empty((n_path, 2), dtype=np.int32)
    cells[:, 0] = flat // w
    cells[:, 1] = flat % w
    return GridPath(cost=float(ws.g[gr * w + gc]) / STRAIGHT * resolution, cells=cells)


def _as_u8(navigable: np.ndarray) -> np.ndarray:
    if navigable.ndim != 2:
        raise ValueError(f"navigable must be a [H, W] array, got shape {navigable.shape}")
    return np.ascontiguousarray(navigable, dtype=np.uint8)


@numba.njit(cache=True)
def _octile(r, c, gr, gc):
    dr = abs(r - gr)
    dc = abs(c - gc)
    lo = min(dr, dc)
    return (dr + dc - 2 * lo) * STRAIGHT + DIAGONAL * lo


@numba.njit(cache=True, inline="always")
def _before(fa, ga, fb, gb):
    """Heap order: smaller f first; on equal f, larger g (deeper) first."""
    return fa < fb or (fa == fb and ga > gb)


@numba.njit(cache=True)
def _push(hf, hg, hn, size, f, g, node):
    i = size
    while i > 0:
        up = (i - 1) >> 1
        if not _before(f, g, hf[up], hg[up]):
            break
        hf[i], hg[i], hn[i] = hf[up], hg[up], hn[up]
        i = up
    hf[i], hg[i], hn[i] = f, g, node


@numba.njit(cache=True)
def _pop_last_into_root(hf, hg, hn, size):
    """Move entry `size` (the old last) to the root and sift it down; `size` is the new heap size."""
    f, g, node = hf[size], hg[size], hn[size]
    i = 0
    while True:
        child = 2 * i + 1
        if child >= size:
            break
        right = child + 1
        if right < size and _before(hf[right], hg[right], hf[child], hg[child]):
            child = right
        if not _before(hf[child], hg[child], f, g):
            break
        hf[i], hg[i], hn[i] = hf[child], hg[child], hn[child]
        i = child
    hf[i], hg[i], hn[i] = f, g, node


@numba.njit(cache=True, inline="always")
def _free(nav, r, c):
    return 0 <= r < nav.shape[0] and 0 <= c < nav.shape[1] and nav[r, c] != 0


@numba.njit(cache=True)
def _jump_straight(nav, r, c, dr, dc, gr, gc):
    """Walk from (r, c) along a straight (dr, dc) to the next jump point: the goal, or a cell with a
    forced neighbour (a free side cell whose cell behind is blocked). (-1, -1) when a wall comes first."""
    while True:
        r += dr
        c += dc
        if not _free(nav, r, c):
            return -1, -1
        if r == gr and c == gc:
            return r, c
        for s in (-1, 1):
            if dr == 0:
                if _free(nav, r + s, c) and not _free(nav, r + s, c - dc):
                    return r, c
            elif _free(nav, r, c + s) and not _free(nav, r - dr, c + s):
                return r, c


@numba.njit(cache=True)
def _jump(nav, r, c, dr, dc, gr, gc):
    """The next jump point from (r, c) in direction (dr, dc), or (-1, -1).

    A diagonal step needs both orthogonal cells free (no corner cutting), so diagonal moves have no
    forced neighbours; a diagonal cell is a jump point when a straight jump from it finds one.
    """
    if dr == 0 or dc == 0:
        return _jump_straight(nav, r, c, dr, dc, gr, gc)
    while True:
        if not (_free(nav, r + dr, c) and _free(nav, r, c + dc) and _free(nav, r + dr, c + dc)):
            return -1, -1
        r += dr
        c += dc
        if r == gr and c == gc:
            return r, c
        if _jump_straight(nav, r, c, dr, 0, gr, gc)[0] >= 0 or _jump_straight(nav, r, c, 0, dc, gr, gc)[0] >= 0:
            return r, c


@numba.njit(cache=True)
def _directions(nav, r, c, pdr, pdc, out):
    """Fill out[:n] with the pruned search directions at (r, c) reached by a move along (pdr, pdc); return n.

    Every cell another route reaches at least as cheaply without passing (r, c) is pruned (ties go
    to diagonal-first routes); a start cell (0, 0) keeps all eight directions.
    """
    n = 0
    if pdr == 0 and pdc == 0:
        for k in range(8):
            out[n, 0], out[n, 1] = _DR[k], _DC[k]
            n += 1
        return n
    if pdr != 0 and pdc != 0:
        out[0, 0], out[0, 1] = pdr, 0
        out[1, 0], out[1, 1] = 0, pdc
        out[2, 0], out[2, 1] = pdr, pdc
        return 3
    out[0, 0], out[0, 1] = pdr, pdc
    n = 1
    for s in (-1, 1):
        if pdr == 0:  # along a row; side cells are above and below
            if _free(nav, r + s, c) and not _free(nav, r + s, c - pdc):
                out[n, 0], out[n, 1] = s, 0
                out[n + 1, 0], out[n + 1, 1] = s, pdc
                n += 2
        elif _free(nav, r, c + s) and not _free(nav, r - pdr, c + s):
            out[n, 0], out[n, 1] = 0, s
            out[n + 1, 0], out[n + 1, 1] = pdr, s
            n += 2
    return n


@numba.njit(cache=True)
def _astar_kernel(nav, start, goal, g, parent, stamp, gen, hf, hg, hn):
    """Cells on the path (0: no path, -1: heap full); g/parent then hold the jump-point search tree.

    A* over jump points (jump point search): a successor is the next jump point along a pruned
    direction, g grows by the octile length of that straight or diagonal run. Lazy deletion: a cell
    is pushed again when its cost improves; stale entries are skipped when popped.
    """
    h, w = nav.shape
    sr, sc, gr, gc = start // w, start % w, goal // w, goal % w
    if nav[sr, sc] == 0 or nav[gr, gc] == 0:
        return 0
    cap = hf.shape[0]
    dirs = np.empty((8, 2), dtype=np.int64)
    stamp[start] = gen
    g[start] = 0
    parent[start] = -1
    hf[0], hg[0], hn[0] = _octile(sr, sc, gr, gc), 0, start
    size = 1
    while size > 0:
        cur = hn[0]
        size -= 1
        if size > 0:
            _pop_last_into_root(hf, hg, hn, size)
        if stamp[cur] == gen + 1:
            continue  # a stale entry of a closed cell
        stamp[cur] = gen + 1
        r, c = cur // w, cur % w
        if cur == goal:
            return _path_length(parent, goal, w)
        pdr = pdc = 0
        if parent[cur] >= 0:
            pdr, pdc = np.sign(r - parent[cur] // w), np.sign(c - parent[cur] % w)
        gcur = g[cur]
        for k in range(_directions(nav, r, c, pdr, pdc, dirs)):
            jr, jc = _jump(nav, r, c, dirs[k, 0], dirs[k, 1], gr, gc)
            if jr < 0:
                continue
            nb = jr * w + jc
            cand = gcur + _octile(r, c, jr, jc)  # exact: the run is straight or diagonal
            st = stamp[nb]
            if st == gen + 1 or (st == gen and cand >= g[nb]):
                continue
            if size == cap:
                return -1
            stamp[nb] = gen
            g[nb] = cand
            parent[nb] = cur
            _push(hf, hg, hn, size, cand + _octile(jr, jc, gr, gc), cand, nb)
            size += 1
    return 0


@numba.njit(cache=True)
def _path_length(parent, goal, w):
    """Cells on the path from the start to `goal`, counting every cell of each jump-point run."""
    n = 1
    k = goal
    while parent[k] >= 0:
        p = parent[k]
        n += max(abs(k // w - p // w), abs(k % w - p % w))
        k = p
    return n


@numba.njit(cache=True)
def _trace(parent, goal, n, w):
    """[n] flat indices of every cell from the start to `goal`, filling in each jump-point run."""
    out = np.empty(n, dtype=np.int64)
    i = n - 1
    k = goal
    out[i] = k
    while parent[k] >= 0:
        p = parent[k]
        dr, dc = np.sign(p // w - k // w), np.sign(p % w - k % w)
        r, c = k // w, k % w
        while r * w + c != p:
            r += dr
            c += dc
            i -= 1
            out[i] = r * w + c
        k = p
    return out
