"""decompose_meshes: exact parts where the mesh is convex pieces, one CoACD batch for the rest."""

from __future__ import annotations

import numpy as np
import trimesh

from sagebench.collider_export import coacd_cache
from sagebench.collider_export.coacd_cache import CoacdParams, PartCache
from sagebench.collider_export.decompose import decompose_meshes
from tests.test_collider_convex import u_prism


def test_mixed_mesh_gets_exact_parts_and_coacd_parts(monkeypatch, tmp_path):
    seen: list[str] = []

    def fake(vertices, faces, params):
        seen.append(f"{len(faces)} faces")
        return [(trimesh.convex.convex_hull(vertices).vertices, np.zeros((0, 3)))]

    monkeypatch.setattr(coacd_cache, "run_coacd", fake)
    table = trimesh.util.concatenate([trimesh.creation.box((1, 1, 0.05)).apply_translation((0, 0, 0.7)),
                                      trimesh.creation.box((0.05, 0.05, 0.7)).apply_translation((0, 0, 0.35))])
    u = u_prism()
    mixed = trimesh.util.concatenate([table, u.copy().apply_translation((3, 0, 0))])
    meshes = {name: (m.vertices, m.faces) for name, m in
              {"meshes/table.ply": table, "meshes/mixed.glb": mixed, "meshes/u.obj": u}.items()}
    out = decompose_meshes(meshes, CoacdParams(), cache=PartCache(tmp_path))
    assert (out["meshes/table.ply"].exact_parts, len(out["meshes/table.ply"].parts)) == (2, 2)
    assert out["meshes/table.ply"].pieces == []
    assert (out["meshes/mixed.glb"].exact_parts, len(out["meshes/mixed.glb"].parts)) == (2, 3)
    assert (out["meshes/u.obj"].exact_parts, len(out["meshes/u.obj"].parts)) == (0, 1)
    # the U inside `mixed` is moved, so it is a different piece from meshes/u.obj: two runs
    assert len(seen) == 2
    assert [p.source for p in out["meshes/mixed.glb"].pieces] == ["coacd"]
