"""Pieces in killable workers: the methods each mode tries, the safety limit, de-duplication, the cache."""

from __future__ import annotations

import numpy as np
import pytest
import shapely
import trimesh
from scipy.spatial import ConvexHull
from shapely.geometry import Polygon

from sagebench.collider_export import pieces as pieces_mod
from sagebench.collider_export.coacd_cache import PartCache
from sagebench.collider_export.convex import ConvexPart
from sagebench.collider_export.methods import LADDERS, ladder
from sagebench.collider_export.pieces import Piece, decompose_pieces, piece_key
from sagebench.errors import ColliderError
from sagebench.settings.export_usd import CoacdParams, ColliderSettings
from tests.test_collider_convex import u_prism
from tests.test_collider_quality import BAND

FAST_COACD = CoacdParams(preprocess_mode="off", max_convex_hull=8)  # the U prism is clean and watertight
QUALITY = ColliderSettings(mode="quality", coacd=FAST_COACD)
BALANCED = ColliderSettings(mode="balanced", coacd=FAST_COACD)
U_OUTLINE = Polygon([(0, 0), (0.6, 0), (0.6, 0.4), (0.45, 0.4), (0.45, 0.1), (0.15, 0.1), (0.15, 0.4), (0, 0.4)])
U_HEIGHT = 0.3


def inside_parts(points: np.ndarray, parts: list[ConvexPart], eps: float = 1e-6) -> np.ndarray:
    """[N] bool: the point lies in at least one convex part (half-space test on each hull)."""
    hit = np.zeros(len(points), bool)
    for part in parts:
        eq = ConvexHull(part.vertices).equations  # [F, 4]: n . x + d <= 0 inside
        hit |= np.all(points @ eq[:, :3].T + eq[:, 3] <= eps, axis=1)
    return hit


def _u(methods=("coacd",)) -> Piece:
    m = u_prism()
    return Piece("u", m.vertices, m.faces, methods)


@pytest.fixture(scope="module")
def u_coacd(tmp_path_factory):
    """One real CoACD run on the U prism, cached in a fresh directory (reused by the tests below)."""
    cache_dir = tmp_path_factory.mktemp("piece-cache")
    (result,) = decompose_pieces([_u(LADDERS["quality"])], QUALITY, cache=PartCache(cache_dir), band=BAND)
    return result, cache_dir


def test_coacd_parts_cover_the_u(u_coacd):
    """Union of the parts vs the U (known in closed form), on a 2 cm grid: within 2 % of its volume,
    and at least 99 % of the U's points covered."""
    result, _ = u_coacd
    assert result.method == "coacd" and not result.cached and len(result.parts) >= 3
    step = 0.02  # the grid is offset so that no point lies on a face of the U
    xs, ys, zs = (np.arange(lo + 0.0037, hi, step) for lo, hi in ((-0.1, 0.7), (-0.1, 0.5), (-0.1, 0.4)))
    pts = np.stack(np.meshgrid(xs, ys, zs, indexing="ij"), axis=-1).reshape(-1, 3)
    in_mesh = shapely.contains_xy(U_OUTLINE, pts[:, 0], pts[:, 1]) & (pts[:, 2] > 0) & (pts[:, 2] < U_HEIGHT)
    in_union = inside_parts(pts, result.parts)
    assert abs(in_union.sum() - in_mesh.sum()) <= 0.02 * in_mesh.sum()
    assert (in_union & in_mesh).sum() >= 0.99 * in_mesh.sum()
    assert result.band_error_cm <= 2.0


def test_second_run_reads_the_cache_without_workers(u_coacd, monkeypatch):
    first, cache_dir = u_coacd
    monkeypatch.setattr(pieces_mod, "_Scheduler", lambda *a: pytest.fail("a worker started despite a cache hit"))
    (again,) = decompose_pieces([_u(LADDERS["quality"])], QUALITY, cache=PartCache(cache_dir), band=BAND)
    assert again.cached and (again.key, again.method) == (first.key, "coacd")
    for a, b in zip(again.parts, first.parts, strict=True):
        assert np.array_equal(a.vertices, b.vertices) and np.array_equal(a.faces, b.faces)


def test_balanced_keeps_the_hull_of_a_box_and_voxels_the_u(tmp_path):
    box = trimesh.creation.box((0.5, 0.4, 0.6)).apply_translation((0, 0, 0.3))
    results = decompose_pieces([Piece("box", box.vertices, box.faces, LADDERS["balanced"]), _u(LADDERS["balanced"])],
                               BALANCED, cache=PartCache(tmp_path), band=BAND)
    assert (results[0].method, len(results[0].parts), results[0].band_error_cm) == ("hull", 1, 0.0)
    # the U's hull bridges its 0.3 m notch (15 cm off in the band); its voxel boxes are within a cell
    assert results[1].method == "voxel" and results[1].band_error_cm <= BALANCED.band_tolerance_cm


def test_a_method_past_the_safety_limit_fails_the_batch_naming_the_piece_and_caches_nothing(tmp_path):
    """The clock never picks a method: CoACD still running at the limit is an error, not a fall back to voxels."""
    slow = ColliderSettings(mode="quality", piece_limit_s=1.0,
                            coacd=CoacdParams(preprocess_mode="on", preprocess_resolution=200, resolution=20000))
    with pytest.raises(ColliderError) as err:
        decompose_pieces([_u(LADDERS["quality"])], slow, cache=PartCache(tmp_path), band=BAND)
    assert str(err.value) == ("u: coacd still running after 1 s, the safety limit (--piece-limit); nothing was "
                              "written: raise the limit, or choose a --colliders mode without this method")
    assert not list(tmp_path.rglob("*.npz"))


def test_the_safety_limit_is_not_part_of_the_cache_key_and_coacd_is_left_out_of_big_pieces():
    m = u_prism()
    piece = Piece("u", m.vertices, m.faces, LADDERS["quality"])
    assert piece_key(piece, QUALITY, BAND) == piece_key(piece, QUALITY.model_copy(update={"piece_limit_s": 5.0}), BAND)
    assert piece_key(piece, QUALITY, BAND) != piece_key(piece, QUALITY.model_copy(update={"coacd_max_faces": 5}), BAND)
    few = QUALITY.model_copy(update={"coacd_max_faces": len(m.faces)})
    assert ladder(few, len(m.faces)) == ("coacd", "voxel", "hull", "coacd_fine", "voxel_exact")
    assert ladder(few, len(m.faces) + 1) == ("voxel", "hull", "voxel_exact")
    assert ladder(BALANCED.model_copy(update={"coacd_max_faces": 0}), 1) == ("hull", "voxel", "voxel_exact")
    assert ladder(BALANCED.model_copy(update={"mode": "fast"}), 1) == ("hull", "voxel", "voxel_exact")  # no CoACD


def test_equal_pieces_run_once_and_workers_do_not_change_results(tmp_path):
    m = u_prism()
    pieces = [Piece("a", m.vertices, m.faces, ("voxel",)), Piece("b", m.vertices.copy(), m.faces.copy(), ("voxel",)),
              Piece("c", m.vertices * 2, m.faces, ("voxel",))]
    one = decompose_pieces(pieces, BALANCED, cache=PartCache(tmp_path / "one"), band=BAND)
    assert one[0] is one[1] and one[0].key != one[2].key
    assert len(list((tmp_path / "one").rglob("*.npz"))) == 2
    two = decompose_pieces(pieces, BALANCED, cache=PartCache(tmp_path / "two"), workers=2, band=BAND)
    for a, b in zip(one, two, strict=True):
        assert a.key == b.key and len(a.parts) == len(b.parts)
        assert all(np.array_equal(p.vertices, q.vertices) for p, q in zip(a.parts, b.parts))


def test_progress_reaches_stderr_without_a_terminal(tmp_path, capsys):
    decompose_pieces([_u(("hull",))], BALANCED, cache=PartCache(tmp_path), band=BAND)
    assert "colliders: 1/1 pieces in " in capsys.readouterr().err  # capsys's stderr is not a TTY
