"""Instance ids for trained Gaussians: the object whose surface is nearest, within a tolerance."""

from __future__ import annotations

import numpy as np
import trimesh
from scipy.spatial import cKDTree

from sagebench.splats.from_mesh import sample_surface


def assign_instances(means: np.ndarray, meshes: dict[int, trimesh.Trimesh], *, tolerance: float = 0.05) -> np.ndarray:
    """[N, 3] Gaussian centres (world m) -> [N] int32 instance id of the nearest surface; 0 beyond `tolerance`.

    Distances are measured to a dense even sampling of every surface (tolerance / 2 apart), so a centre
    on a surface is always within tolerance of a sample and the error is below the sample spacing.
    """
    if tolerance <= 0:
        raise ValueError(f"tolerance must be positive, got {tolerance}")
    rng = np.random.default_rng(0)
    points, owners = [], []
    for instance_id in sorted(meshes):
        mesh = meshes[instance_id]
        face, bary = sample_surface(mesh, tolerance / 2, rng)
        # vertices too, so tiny parts smaller than the spacing are never missed
        points += [np.einsum("mk,mkc->mc", bary, mesh.triangles[face]), np.asarray(mesh.vertices, np.float64)]
        owners += [np.full(len(face) + len(mesh.vertices), instance_id, np.int32)]
    if not points:
        return np.zeros(len(means), np.int32)
    tree = cKDTree(np.concatenate(points))
    owner = np.concatenate(owners)
    dist, nearest = tree.query(np.asarray(means, np.float64), k=1, distance_upper_bound=tolerance, workers=-1)
    out = np.zeros(len(means), np.int32)
    hit = np.isfinite(dist)
    out[hit] = owner[nearest[hit]]
    return out
