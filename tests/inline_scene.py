"""Scenes held in memory for the map builder's steps (sagebench/topdown/builder.py): world-space meshes and rooms,
no scene directory, no loader."""

from __future__ import annotations

from pathlib import Path

import trimesh

from sagebench.scene.loader import LoadedScene
from sagebench.scene.model import Room, SceneObject, SceneSpec


def inline_scene(things: list[tuple[str, str, trimesh.Trimesh]], rooms: dict[str, list] | None = None) -> LoadedScene:
    """A LoadedScene of (category, kind, mesh) objects, instance ids 1.. in order, and rooms id -> [x, y] polygon."""
    objects = [SceneObject(instance_id=i, category=category, kind=kind, mesh=f"meshes/{i}.ply")
               for i, (category, kind, _) in enumerate(things, start=1)]
    spec = SceneSpec(scene_id="inline", objects=objects,
                     rooms=[Room(id=r, type="room", polygon=p) for r, p in (rooms or {}).items()])
    meshes = {i: mesh for i, (_, _, mesh) in enumerate(things, start=1)}
    return LoadedScene(spec=spec, meshes=meshes, source_dir=Path("inline"), source_sha256="")
