"""Dynamic time warping between two XY point sequences (the DP of nDTW), compiled with numba."""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True)
def _dtw(p: np.ndarray, r: np.ndarray) -> float:
    n, m = p.shape[0], r.shape[0]
    prev = np.full(m + 1, np.inf)
    prev[0] = 0.0
    cur = np.empty(m + 1)
    for i in range(1, n + 1):
        cur[0] = np.inf
        for j in range(1, m + 1):
            dx = p[i - 1, 0] - r[j - 1, 0]
            dy = p[i - 1, 1] - r[j - 1, 1]
            best = min(prev[j], cur[j - 1], prev[j - 1])
            cur[j] = np.sqrt(dx * dx + dy * dy) + best
        prev, cur = cur, prev
    return prev[m]


def dtw(query: np.ndarray, reference: np.ndarray) -> float:
    """Sum of XY distances along the cheapest monotone alignment.  query: [N, >=2], reference: [M, >=2]."""
    q = np.ascontiguousarray(np.asarray(query, dtype=np.float64)[:, :2])
    r = np.ascontiguousarray(np.asarray(reference, dtype=np.float64)[:, :2])
    if len(q) == 0 or len(r) == 0:
        raise ValueError("dtw needs two non-empty sequences")
    return float(_dtw(q, r))
