"""SAGE-3D's released per-scene collision USD (`<id>_collision.usd`) as meshes for an InteriorGS import's objects.

Every `UsdGeom.Mesh` prim is read in the stage's world (its transforms applied, an authored `metersPerUnit` and
Y-up axis turned to metres, Z up; unauthored, metres and Z up as in the stage SAGE-3D composes it into) and split into connected pieces; a piece belongs to the labelled box that holds
most of its vertices (at least half). SAGE-3D's own USD template turns the collision payload by 180 degrees
about Z, so the file's frame is not documented: of the file as it is and the file turned by 180 degrees about
Z, the one whose pieces fall into the boxes more often is taken (the report says which).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import trimesh

from sagebench.errors import DataError
from sagebench.importers.boxes import OrientedBox

MATCH_SHARE = 0.5  # a piece belongs to a box holding at least this share of its vertices
BOX_MARGIN_M = 0.02  # boxes are grown by this for the test
TURNED = np.diag([-1.0, -1.0, 1.0])  # 180 degrees about Z


@dataclass(frozen=True)
class CollisionMatch:
    meshes: dict[int, trimesh.Trimesh]  # box index -> the pieces it holds (world m)
    prims: int
    pieces: int
    matched_pieces: int
    turned: bool  # whether the file's frame was turned by 180 degrees about Z


def read_usd_meshes(path: Path) -> list[trimesh.Trimesh]:
    """Every mesh prim of the USD file, triangulated, in world metres with Z up."""
    from pxr import Usd, UsdGeom

    try:
        stage = Usd.Stage.Open(str(path))
    except Exception as err:  # pxr raises Tf.ErrorException with several lines
        raise DataError(f"cannot open as USD: {str(err).splitlines()[0] if str(err) else err}", path=path) from None
    if stage is None:
        raise DataError("cannot open as USD", path=path)
    # unauthored, USD would assume centimetres and Y up; SAGE-3D's files are composed into a metres, Z-up stage
    # without conversion, so what is not authored is taken as metres and Z up
    scale = UsdGeom.GetStageMetersPerUnit(stage) if stage.HasAuthoredMetadata("metersPerUnit") else 1.0
    y_up = stage.HasAuthoredMetadata("upAxis") and UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.y
    frame = np.array([[1.0, 0, 0], [0, 0, -1.0], [0, 1.0, 0]]) if y_up else np.eye(3)  # Y up -> Z up
    cache = UsdGeom.XformCache()
    out = []
    for prim in stage.Traverse():
        if not prim.IsA(UsdGeom.Mesh):
            continue
        mesh = UsdGeom.Mesh(prim)
        points = np.asarray(mesh.GetPointsAttr().Get() or [], dtype=np.float64).reshape(-1, 3)
        counts = np.asarray(mesh.GetFaceVertexCountsAttr().Get() or [], dtype=np.int64)
        indices = np.asarray(mesh.GetFaceVertexIndicesAttr().Get() or [], dtype=np.int64)
        if not len(points) or not len(counts) or counts.sum() != len(indices) or (indices >= len(points)).any():
            continue
        matrix = np.asarray(cache.GetLocalToWorldTransform(prim), dtype=np.float64)  # row vectors: p' = p M
        world = (np.column_stack([points, np.ones(len(points))]) @ matrix)[:, :3] @ frame.T * scale
        starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
        tris = [indices[[s, s + k, s + k + 1]] for s, n in zip(starts, counts) for k in range(1, n - 1)]
        if tris:
            out.append(trimesh.Trimesh(world, np.asarray(tris), process=False))
    return out


def match_collision_meshes(path: Path, boxes: list[OrientedBox]) -> CollisionMatch:
    """The collision file's pieces grouped by the box (index into `boxes`) each belongs to."""
    meshes = read_usd_meshes(path)
    if not meshes:
        raise DataError("holds no UsdGeom.Mesh prim with faces", path=path)
    pieces = [p for m in meshes for p in m.split(only_watertight=False)]
    best = None
    for turned in (False, True):
        owners = [_owner(p.vertices @ (TURNED.T if turned else np.eye(3)), boxes) for p in pieces]
        hits = sum(o >= 0 for o in owners)
        if best is None or hits > best[0]:
            best = (hits, turned, owners)
    hits, turned, owners = best
    grouped: dict[int, list[trimesh.Trimesh]] = {}
    for piece, owner in zip(pieces, owners):
        if owner >= 0:
            piece = piece.copy()
            if turned:
                piece.vertices = piece.vertices @ TURNED.T
            grouped.setdefault(owner, []).append(piece)
    return CollisionMatch({k: trimesh.util.concatenate(v) for k, v in sorted(grouped.items())}, len(meshes),
                          len(pieces), hits, turned)


def _owner(vertices: np.ndarray, boxes: list[OrientedBox]) -> int:
    """The box holding the largest share of `vertices` if at least MATCH_SHARE, else -1."""
    shares = [float(b.contains(vertices, BOX_MARGIN_M).mean()) for b in boxes]
    if not shares or max(shares) < MATCH_SHARE:
        return -1
    return int(np.argmax(shares))
