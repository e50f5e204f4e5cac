"""A scene's visual meshes as one GLB in habitat's frame (Y up), for habitat-sim to render and navmesh."""

from __future__ import annotations

import numpy as np
import trimesh

from sagebench.scene.loader import LoadedScene
from sagebench.vlnce.frame import HABITAT_FROM_WORLD


def scene_glb(scene: LoadedScene) -> bytes:
    """Every object's mesh (world frame, doors at their state's angle) turned into habitat's frame, one node
    per object named <category>_<instance_id>; colours and textures as loaded."""
    turn = np.eye(4)
    turn[:3, :3] = HABITAT_FROM_WORLD
    out = trimesh.Scene()
    for obj in scene.spec.objects:
        mesh = scene.meshes[obj.instance_id].copy()
        mesh.apply_transform(turn)
        name = f"{obj.category}_{obj.instance_id}"
        out.add_geometry(mesh, node_name=name, geom_name=name)
    return out.export(file_type="glb")
