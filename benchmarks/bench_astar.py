"""Grid A* per query: sagebench's numba A* against scikit-image MCP_Geometric and pyastar2d, same queries.

Grids: the demo scene's navigable map, and deterministic 400x400 / 1000x1000 office floors and mazes.
Every method's path cost is checked against the Dijkstra reference (scipy, no corner cutting). Note
the references solve slightly different problems: pyastar2d charges a diagonal step like a straight
one (its paths are optimal for that metric, longer in metres) and both references may cut corners.
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

import numpy as np
from scipy import ndimage
from scipy.sparse.csgraph import dijkstra

from sagebench.astar.dijkstra_reference import grid_graph, path_cost
from sagebench.astar.grid_astar import Workspace, astar

RES = 0.05


def office_grid(n: int, seed: int = 0) -> np.ndarray:
    """[n, n] uint8 navigable: 5 m rooms off corridors, doors in most walls, desks and cabinets inside."""
    rng = np.random.default_rng(seed)
    nav = np.ones((n, n), dtype=np.uint8)
    room, wall, door = 100, 4, 20  # cells: 5 m rooms, 0.2 m walls, 1 m doors
    for k in range(0, n + 1, room):
        nav[max(k - wall // 2, 0):k + wall // 2, :] = 0
        nav[:, max(k - wall // 2, 0):k + wall // 2] = 0
    for i in range(0, n, room):
        for j in range(0, n, room):
            off = [int(v) for v in rng.integers(wall + 2, room - door - wall - 2, 2)]
            doors = rng.random(2) < 0.85  # a door in the room's south and west walls, most of the time
            if i > 0 and doors[0]:
                nav[i - wall // 2:i + wall // 2, j + off[0]:j + off[0] + door] = 1
            if j > 0 and doors[1]:
                nav[i + off[1]:i + off[1] + door, j - wall // 2:j + wall // 2] = 1
            for _ in range(int(rng.integers(2, 5))):  # furniture, kept off the walls so doors stay usable
                h, w = (int(v) for v in rng.integers(12, 36, 2))
                r, c = (int(v) for v in rng.integers(wall + 16, room - wall - 16 - 36, 2))
                nav[i + r:i + r + h, j + c:j + c + w] = 0
    nav[[0, -1], :] = 0
    nav[:, [0, -1]] = 0
    return nav


def maze_grid(n: int, seed: int = 0, corridor: int = 8, wall: int = 2) -> np.ndarray:
    """[n, n] uint8 navigable: a perfect maze (iterative depth-first backtracker) with `corridor`-cell passages."""
    rng = np.random.default_rng(seed)
    pitch = corridor + wall
    m = (n - wall) // pitch
    nav = np.zeros((n, n), dtype=np.uint8)
    seen = np.zeros((m, m), dtype=bool)
    stack = [(0, 0)]
    seen[0, 0] = True

    def open_cell(a: int, b: int) -> None:
        nav[wall + a * pitch:wall + a * pitch + corridor, wall + b * pitch:wall + b * pitch + corridor] = 1

    open_cell(0, 0)
    while stack:
        a, b = stack[-1]
        nbrs = [(a + da, b + db) for da, db in ((1, 0), (-1, 0), (0, 1), (0, -1))
                if 0 <= a + da < m and 0 <= b + db < m and not seen[a + da, b + db]]
        if not nbrs:
            stack.pop()
            continue
        na, nb = nbrs[int(rng.integers(len(nbrs)))]
        seen[na, nb] = True
        open_cell(na, nb)
        r0, r1 = sorted((wall + a * pitch, wall + na * pitch))
        c0, c1 = sorted((wall + b * pitch, wall + nb * pitch))
        nav[r0:r1 + corridor, c0:c1 + corridor] = 1  # knock down the wall between the two cells
        stack.append((na, nb))
    return nav


def demo_grid() -> np.ndarray:
    from sagebench.scene.synth import write_synth_scene
    from sagebench.stages.build_scene import build_scene

    with tempfile.TemporaryDirectory() as tmp:
        write_synth_scene(Path(tmp) / "scene", seed=0)
        out = build_scene(Path(tmp) / "scene", Path(tmp) / "run").out_dir
        with np.load(out / "topdown.npz") as npz:
            return (npz["navigable"] != 0).astype(np.uint8)


def queries(nav: np.ndarray, k: int, seed: int = 1) -> list[tuple[tuple[int, int], tuple[int, int]]]:
    """k start/goal pairs in the largest 4-connected component, at least a third of the diagonal apart."""
    labels, _ = ndimage.label(nav)
    big = np.argmax(np.bincount(labels.ravel())[1:]) + 1
    cells = np.argwhere(labels == big)
    rng = np.random.default_rng(seed)
    out = []
    min_d = np.hypot(*nav.shape) / 3
    while len(out) < k:
        a, b = cells[rng.integers(len(cells), size=2)]
        if np.hypot(*(a - b)) >= min_d:
            out.append(((int(a[0]), int(a[1])), (int(b[0]), int(b[1]))))
    return out


def _corner_cuts(nav: np.ndarray, cells: np.ndarray) -> int:
    steps = np.diff(cells.astype(int), axis=0)
    diag = (steps[:, 0] != 0) & (steps[:, 1] != 0)
    r, c = cells[:-1, 0].astype(int), cells[:-1, 1].astype(int)
    blocked = (nav[r + steps[:, 0], c] == 0) | (nav[r, c + steps[:, 1]] == 0)
    return int((diag & blocked).sum())


def _bench_grid(name: str, nav: np.ndarray, n_queries: int) -> list[dict]:
    import pyastar2d
    from skimage.graph import MCP_Geometric

    qs = queries(nav, n_queries)
    graph = grid_graph(nav).tocsr()
    w = nav.shape[1]
    truth = [float(dijkstra(graph, indices=s[0] * w + s[1])[g[0] * w + g[1]]) * RES for s, g in qs]

    ws = Workspace(nav.shape)
    astar(nav, *qs[0], RES, ws)  # JIT load outside the timing
    weights = np.where(nav != 0, 1.0, np.inf).astype(np.float32)
    mcp = MCP_Geometric(weights.astype(np.float64), fully_connected=True)

    def ours(s, g):
        p = astar(nav, s, g, RES, ws)
        return p.cells

    def py_astar(s, g):
        return pyastar2d.astar_path(weights, s, g, allow_diagonal=True)

    def skimage_mcp(s, g):
        mcp.find_costs([s], [g], find_all_ends=True)
        return np.array(mcp.traceback(g))

    results = {}
    for label, fn in (("sagebench A*", ours), ("pyastar2d", py_astar), ("skimage MCP_Geometric", skimage_mcp)):
        times, errs, cuts = [], [], 0
        for (s, g), want in zip(qs, truth, strict=True):
            t0 = time.perf_counter()
            cells = fn(s, g)
            times.append(time.perf_counter() - t0)
            errs.append(path_cost(cells, RES) / want - 1)
            cuts += _corner_cuts(nav, cells)
        results[label] = (float(np.mean(times)), max(errs, key=abs), cuts)

    ours_t, ours_err, ours_cuts = results["sagebench A*"]
    rows = []
    for label in ("pyastar2d", "skimage MCP_Geometric"):
        ref_t, ref_err, ref_cuts = results[label]
        rows.append({
            "name": f"A* {name} ({nav.shape[0]}x{nav.shape[1]}, {len(qs)} queries)",
            "reference": label,
            "seconds": ours_t,
            "reference seconds": ref_t,
            "speed-up": ref_t / ours_t,
            "cost vs Dijkstra": f"ours {ours_err:+.1e}, ref {ref_err:+.2%}",
            "notes": f"corner cuts: ours {ours_cuts}, ref {ref_cuts}",
        })
    return rows


def run() -> list[dict]:
    rows = _bench_grid("demo scene", demo_grid(), 40)
    for n, q in ((400, 20), (1000, 8)):
        rows += _bench_grid(f"office {n}", office_grid(n), q)
        rows += _bench_grid(f"maze {n}", maze_grid(n), q)
    return rows


if __name__ == "__main__":
    for row in run():
        print(row)
