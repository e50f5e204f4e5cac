"""What a mesh file may cost before it is read: its size, and its face count read from its header, streaming.

A mesh is loaded whole (trimesh), copied into the run and decomposed into colliders; MuJoCo then reads each
collider part as an STL of at most 200,000 faces. A mesh within MAX_MESH_FACES keeps every part within that
(a part is at most the convex hull of the mesh's vertices, which has fewer faces than a closed mesh), and the
checks here refuse anything bigger from its size or its header alone, before the file is read.
"""

from __future__ import annotations

import json
import re
import struct
from pathlib import Path

MAX_MESH_FACES = 200_000  # MuJoCo's stl_decoder refuses an STL of more faces
MAX_MESH_BYTES = 1 << 30  # 1 GiB: a 200,000-face mesh with its textures embedded is far smaller
CHUNK = 1 << 20
_PLY_FACES = re.compile(rb"^element\s+face\s+(\d+)\s*$", re.M)


def budget_problem(path: Path) -> str | None:
    """Why the mesh file is over the budget, from its size and header (None when within it or unknown)."""
    size = path.stat().st_size
    if size > MAX_MESH_BYTES:
        return f"is {size / 2**30:.1f} GiB, over the budget of {MAX_MESH_BYTES / 2**30:g} GiB per mesh file"
    faces = declared_faces(path)
    if faces is not None and faces > MAX_MESH_FACES:
        return faces_problem(faces)
    return None


def faces_problem(faces: int) -> str:
    return (f"has {faces:,} faces, over the budget of {MAX_MESH_FACES:,} (MuJoCo's limit for one collider mesh): "
            "decimate it first")


def declared_faces(path: Path) -> int | None:
    """Triangles the file says it holds: a PLY's face element, a glTF/GLB's index (or position) accessors per mesh
    instance, an OBJ's face lines (counted in chunks). None when the header cannot tell (the loader then decides)."""
    suffix = path.suffix.lower()
    try:
        if suffix == ".ply":
            with open(path, "rb") as fh:
                head = fh.read(1 << 16)
            end = head.find(b"end_header")
            m = _PLY_FACES.search(head[: end if end >= 0 else len(head)])
            return int(m.group(1)) if m else None
        if suffix == ".obj":
            return _obj_faces(path)
        if suffix in (".glb", ".gltf"):
            doc = _gltf_json(path, suffix)
            return None if doc is None else _gltf_triangles(doc)
    except (OSError, ValueError, KeyError, TypeError, IndexError, AttributeError, RecursionError, struct.error):
        return None
    return None


def _obj_faces(path: Path) -> int:
    count, tail = 0, b"\n"
    with open(path, "rb") as fh:
        for chunk in iter(lambda: fh.read(CHUNK), b""):
            text = tail[-1:] + chunk
            count += text.count(b"\nf ") + text.count(b"\nf\t")
            tail = chunk
    return count


def _gltf_json(path: Path, suffix: str) -> dict | None:
    with open(path, "rb") as fh:
        if suffix == ".gltf":
            if path.stat().st_size > 64 * CHUNK:
                return None
            return json.loads(fh.read())
        magic, _, _ = struct.unpack("<4sII", fh.read(12))
        length, kind = struct.unpack("<I4s", fh.read(8))
        if magic != b"glTF" or kind != b"JSON" or length > 64 * CHUNK:
            return None
        return json.loads(fh.read(length))


def _gltf_triangles(doc: dict) -> int:
    accessors = doc.get("accessors", [])
    per_mesh = []
    for mesh in doc.get("meshes", []):
        n = 0
        for prim in mesh.get("primitives", []):
            if prim.get("mode", 4) != 4:
                continue
            acc = prim["indices"] if "indices" in prim else prim["attributes"]["POSITION"]
            n += int(accessors[acc]["count"]) // 3
        per_mesh.append(n)
    uses = [node["mesh"] for node in doc.get("nodes", []) if "mesh" in node]
    return sum(per_mesh[i] for i in uses) if uses else sum(per_mesh)
