"""CoACD runner and content-addressed cache: coverage of the mesh, cache hits, de-duplication, fallback."""

from __future__ import annotations

import numpy as np
import pytest
import shapely
from scipy.spatial import ConvexHull
from shapely.geometry import Polygon

from sagebench.collider_export import coacd_cache
from sagebench.collider_export.coacd_cache import CoacdParams, PartCache, cache_key, decompose_pieces
from sagebench.collider_export.convex import ConvexPart
from tests.test_collider_convex import u_prism

FAST = CoacdParams(preprocess_mode="off", max_convex_hull=8)  # the U prism is clean and watertight
U_OUTLINE = Polygon([(0, 0), (0.6, 0), (0.6, 0.4), (0.45, 0.4), (0.45, 0.1), (0.15, 0.1), (0.15, 0.4), (0, 0.4)])
U_HEIGHT = 0.3


def inside_parts(points: np.ndarray, parts: list[ConvexPart], eps: float = 1e-6) -> np.ndarray:
    """[N] bool: the point lies in at least one convex part (half-space test on each hull)."""
    hit = np.zeros(len(points), bool)
    for part in parts:
        eq = ConvexHull(part.vertices).equations  # [F, 4]: n . x + d <= 0 inside
        hit |= np.all(points @ eq[:, :3].T + eq[:, 3] <= eps, axis=1)
    return hit


@pytest.fixture(scope="session")
def u_parts(tmp_path_factory):
    """One real CoACD run on the U prism, cached in a fresh directory (reused by the tests below)."""
    cache_dir = tmp_path_factory.mktemp("coacd-cache")
    m = u_prism()
    (result,) = decompose_pieces([("u", m.vertices, m.faces)], FAST, cache=PartCache(cache_dir))
    return m, result, cache_dir


def test_coacd_parts_cover_the_mesh(u_parts):
    """Union of the parts vs the U (known in closed form), on a 2 cm grid: within 2 % of its volume,
    and at least 99 % of the U's points covered."""
    _, result, _ = u_parts
    assert result.source == "coacd" and len(result.parts) >= 3
    step = 0.02  # the grid is offset so that no point lies on a face of the U
    xs, ys, zs = (np.arange(lo + 0.0037, hi, step) for lo, hi in ((-0.1, 0.7), (-0.1, 0.5), (-0.1, 0.4)))
    pts = np.stack(np.meshgrid(xs, ys, zs, indexing="ij"), axis=-1).reshape(-1, 3)
    in_mesh = shapely.contains_xy(U_OUTLINE, pts[:, 0], pts[:, 1]) & (pts[:, 2] > 0) & (pts[:, 2] < U_HEIGHT)
    in_union = inside_parts(pts, result.parts)
    assert abs(in_union.sum() - in_mesh.sum()) <= 0.02 * in_mesh.sum()
    assert (in_union & in_mesh).sum() >= 0.99 * in_mesh.sum()


def test_second_run_reads_the_cache(u_parts, monkeypatch):
    m, first, cache_dir = u_parts
    monkeypatch.setattr(coacd_cache, "run_coacd", lambda *a: pytest.fail("CoACD ran despite a cache hit"))
    (again,) = decompose_pieces([("u", m.vertices, m.faces)], FAST, cache=PartCache(cache_dir))
    assert again.source == "cache" and again.key == first.key
    assert len(again.parts) == len(first.parts)
    for a, b in zip(again.parts, first.parts):
        assert np.array_equal(a.vertices, b.vertices) and np.array_equal(a.faces, b.faces)
    assert (cache_dir / coacd_cache.CACHE_SUBDIR / first.key[:2] / f"{first.key}.npz").is_file()


def test_cache_key_depends_on_mesh_and_parameters():
    m = u_prism()
    key = cache_key(m.vertices, m.faces, FAST)
    assert key == cache_key(m.vertices.copy(), m.faces.copy(), CoacdParams(preprocess_mode="off", max_convex_hull=8))
    assert key != cache_key(m.vertices + 1e-9, m.faces, FAST)
    assert key != cache_key(m.vertices, m.faces[::-1], FAST)
    assert key != cache_key(m.vertices, m.faces, FAST.model_copy(update={"threshold": 0.1}))
    assert key != cache_key(m.vertices, m.faces, FAST.model_copy(update={"seed": 1}))


def _fake_coacd(calls: list[int]):
    def run(vertices, faces, params):
        calls.append(len(faces))
        lo, hi = vertices.min(axis=0), vertices.max(axis=0)
        mid = (lo + hi) / 2
        corners = lambda a, b: np.array(np.meshgrid(*zip(a, b), indexing="ij")).reshape(3, -1).T  # noqa: E731
        return [(corners(lo, np.array([mid[0], hi[1], hi[2]])), np.zeros((0, 3))),
                (corners(np.array([mid[0], lo[1], lo[2]]), hi), np.zeros((0, 3)))]
    return run


def test_equal_pieces_decompose_once(monkeypatch, tmp_path):
    calls: list[int] = []
    monkeypatch.setattr(coacd_cache, "run_coacd", _fake_coacd(calls))
    m = u_prism()
    pieces = [("a", m.vertices, m.faces), ("b", m.vertices.copy(), m.faces.copy()), ("c", m.vertices * 2, m.faces)]
    results = decompose_pieces(pieces, FAST, cache=PartCache(tmp_path))
    assert len(calls) == 2
    assert results[0] is results[1] and results[0].key != results[2].key
    assert [len(r.parts) for r in results] == [2, 2, 2]


def test_failure_falls_back_to_the_hull_with_a_warning(monkeypatch, tmp_path, capsys):
    def broken(vertices, faces, params):
        raise RuntimeError("manifold preprocessing failed")

    monkeypatch.setattr(coacd_cache, "run_coacd", broken)
    m = u_prism()
    (result,) = decompose_pieces([("meshes/sofa.glb (concave piece 0)", m.vertices, m.faces)], FAST,
                                 cache=PartCache(tmp_path))
    assert result.source == "hull_fallback"
    assert np.isclose(result.parts[0].volume, m.convex_hull.volume)
    err = capsys.readouterr().err
    assert "warning: meshes/sofa.glb (concave piece 0): CoACD failed (manifold preprocessing failed)" in err
    assert not any(tmp_path.rglob("*.npz"))  # a failure is not cached


def test_process_pool_gives_the_same_parts(u_parts, tmp_path):
    """workers=2 (spawned processes) on two pieces: the same parts as the in-process run, then cached."""
    m, first, _ = u_parts
    moved = m.vertices + np.array([1.0, 0.0, 0.0])
    results = decompose_pieces([("u", m.vertices, m.faces), ("u moved", moved, m.faces)], FAST,
                               cache=PartCache(tmp_path), workers=2)
    assert [r.source for r in results] == ["coacd", "coacd"]
    for a, b in zip(results[0].parts, first.parts):
        assert np.allclose(a.vertices, b.vertices)
    assert len(list(tmp_path.rglob("*.npz"))) == 2


def test_no_cache_directory_means_no_files(monkeypatch, tmp_path):
    monkeypatch.setattr(coacd_cache, "run_coacd", _fake_coacd([]))
    m = u_prism()
    (result,) = decompose_pieces([("u", m.vertices, m.faces)], FAST, cache=PartCache(None))
    assert result.source == "coacd"
