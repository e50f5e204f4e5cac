"""The content-addressed piece cache: keys, round trip, no directory means no files."""

from __future__ import annotations

import numpy as np

from sagebench.collider_export.coacd_cache import CACHE_SUBDIR, PartCache, PieceResult, cache_key
from sagebench.collider_export.convex import hull_part
from sagebench.settings.export_usd import CoacdParams, ColliderSettings
from tests.test_collider_convex import u_prism

SETTINGS = ColliderSettings(mode="quality", coacd=CoacdParams(preprocess_mode="off", max_convex_hull=8))


def test_cache_key_depends_on_mesh_and_settings():
    m = u_prism()
    key = cache_key(m.vertices, m.faces, SETTINGS)
    assert key == cache_key(m.vertices.copy(), m.faces.copy(), ColliderSettings(
        mode="quality", coacd=CoacdParams(preprocess_mode="off", max_convex_hull=8)))
    assert key != cache_key(m.vertices + 1e-9, m.faces, SETTINGS)
    assert key != cache_key(m.vertices, m.faces[::-1], SETTINGS)
    assert key != cache_key(m.vertices, m.faces, SETTINGS.model_copy(update={"mode": "fast"}))
    assert key != cache_key(m.vertices, m.faces, SETTINGS.model_copy(update={"coacd": CoacdParams(seed=1)}))
    assert key != cache_key(m.vertices, m.faces, SETTINGS, floor_height=0.1)


def test_round_trip_keeps_parts_method_and_band_error(tmp_path):
    m = u_prism()
    result = PieceResult([hull_part(m.vertices), hull_part(m.vertices + 1)], "voxel", "ab" + "0" * 62, 1.25)
    cache = PartCache(tmp_path)
    cache.put(result)
    assert (tmp_path / CACHE_SUBDIR / "ab" / f"{result.key}.npz").is_file()
    back = cache.get(result.key)
    assert (back.method, back.key, back.band_error_cm, back.cached) == ("voxel", result.key, 1.25, True)
    for a, b in zip(back.parts, result.parts, strict=True):
        assert np.array_equal(a.vertices, b.vertices) and np.array_equal(a.faces, b.faces)


def test_unreadable_entry_is_ignored_with_a_warning(tmp_path, capsys):
    key = "cd" + "1" * 62
    path = tmp_path / CACHE_SUBDIR / "cd" / f"{key}.npz"
    path.parent.mkdir(parents=True)
    path.write_bytes(b"not a zip")
    assert PartCache(tmp_path).get(key) is None
    assert f"warning: ignoring unreadable cache entry {path}" in capsys.readouterr().err


def test_no_cache_directory_means_no_files(tmp_path):
    cache = PartCache(None)
    cache.put(PieceResult([hull_part(u_prism().vertices)], "hull", "ef" + "2" * 62, 0.0))
    assert cache.get("ef" + "2" * 62) is None and not any(tmp_path.iterdir())
