"""Which pieces of a mesh are already convex solids, so that only the rest needs CoACD.

Artist furniture is often a concatenation of boxes and cylinders: each connected piece is convex
and its hull is an exact collider. A piece is a *convex solid* when it is closed (every edge on two
faces) and its volume equals its hull's volume within a relative tolerance.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import trimesh
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import ConvexHull, QhullError

WELD_DECIMALS = 6  # vertices closer than ~1e-6 m are one vertex
MIN_THICKNESS = 0.01  # m; a flat piece's hull is padded to this thickness so it has a volume
FLAT_BRIDGE = 0.005  # m; a flat piece is its own hull only where that hull bridges no notch of its outline deeper


@dataclass(frozen=True)
class ConvexPart:
    """One convex collider: a closed hull with outward-wound triangles, in the source mesh's frame."""

    vertices: np.ndarray  # [V, 3] float64
    faces: np.ndarray  # [F, 3] int64

    @property
    def volume(self) -> float:
        return float(ConvexHull(self.vertices).volume)


@dataclass(frozen=True)
class ConvexSplit:
    """A mesh as exact convex parts plus the concave pieces (welded vertices, faces) left for CoACD."""

    parts: list[ConvexPart]
    concave: list[tuple[np.ndarray, np.ndarray]]  # ([V, 3] float64, [F, 3] int64) each


def weld(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Merge coincident vertices (rounded to WELD_DECIMALS) and drop the ones no face uses.

    vertices: [V, 3] float, faces: [F, 3] int -> ([V', 3] float64, [F, 3] int64), face order kept.
    """
    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(faces, dtype=np.int64)
    _, first, inverse = np.unique(np.round(v, WELD_DECIMALS), axis=0, return_index=True, return_inverse=True)
    f = inverse.reshape(-1)[f]
    used, f = np.unique(f, return_inverse=True)
    return v[first][used], f.reshape(-1, 3)


def face_components(faces: np.ndarray, n_vertices: int) -> list[np.ndarray]:
    """Face indices of each group of faces joined through shared vertices, in order of first face."""
    f = np.asarray(faces, dtype=np.int64)
    rows = np.concatenate([f[:, 0], f[:, 1]])
    cols = np.concatenate([f[:, 1], f[:, 2]])
    graph = coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(n_vertices, n_vertices))
    _, label = connected_components(graph, directed=False)
    face_label = label[f[:, 0]]
    _, first = np.unique(face_label, return_index=True)
    return [np.flatnonzero(face_label == face_label[i]) for i in np.sort(first)]


def hull_part(points: np.ndarray) -> ConvexPart:
    """The convex hull of `points` [N, 3]; along any direction thinner than MIN_THICKNESS it is padded first."""
    pts = np.asarray(points, dtype=np.float64)
    for direction, extent in zip(*_principal_extents(pts)):
        if extent < MIN_THICKNESS:
            shift = direction[None, :] * (MIN_THICKNESS - extent) / 2
            pts = np.concatenate([pts + shift, pts - shift])
    return ConvexPart(*oriented_hull(pts))


def oriented_hull(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Qhull's hull of `points` [N, 3]: its vertices [V, 3] (in input order) and triangles [F, 3] wound
    outward by qhull's own facet planes. (trimesh.convex.convex_hull winds by
    the direction from the centroid, which turns faces inward on long thin hulls.)"""
    hull = ConvexHull(points, qhull_options="QbB Pp Qt")
    used = np.sort(hull.vertices)
    index = np.zeros(len(points), dtype=np.int64)
    index[used] = np.arange(len(used))
    vertices = np.asarray(points, dtype=np.float64)[used]
    faces = index[hull.simplices]
    cross = np.cross(vertices[faces[:, 1]] - vertices[faces[:, 0]], vertices[faces[:, 2]] - vertices[faces[:, 0]])
    inward = np.einsum("ij,ij->i", cross, hull.equations[:, :3]) < 0
    faces[inward] = faces[inward][:, ::-1]
    return vertices, faces


def _principal_extents(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Principal directions [3, 3] (rows) of a point set and its extent [3] along each, thinnest last."""
    centred = points - points.mean(axis=0)
    _, vecs = np.linalg.eigh(centred.T @ centred)  # ascending eigenvalues: thinnest direction first
    vt = vecs.T[::-1]
    return vt, np.ptp(centred @ vt.T, axis=0)


def _hull_volume(points: np.ndarray) -> float:
    try:
        return float(ConvexHull(points).volume)
    except (QhullError, ValueError):
        return 0.0


def is_convex_solid(vertices: np.ndarray, faces: np.ndarray, *, tolerance: float) -> bool:
    """Closed, and |volume - hull volume| <= tolerance * hull volume (vertices welded first)."""
    v, f = weld(vertices, faces)
    hull_volume = _hull_volume(v)
    if hull_volume <= 1e-12:
        return False
    mesh = trimesh.Trimesh(v, f, process=False)
    if not mesh.is_watertight:
        return False
    return abs(abs(_signed_volume(mesh)) - hull_volume) <= tolerance * hull_volume


def _signed_volume(mesh: trimesh.Trimesh) -> float:
    """trimesh's volume, quiet: a closed mesh whose faces' volumes cancel (artist meshes with flipped faces) has
    volume 0, and trimesh's centre of mass, computed with it, divides by it and warns on the user's terminal."""
    with np.errstate(divide="ignore", invalid="ignore"):
        return float(mesh.volume)


def is_convex_solid_reference(vertices: np.ndarray, faces: np.ndarray, *, eps: float = 1e-6) -> bool:
    """Textbook check: closed, consistently wound outward, and every vertex behind every face's plane."""
    v, f = weld(vertices, faces)
    mesh = trimesh.Trimesh(v, f, process=False)
    if not mesh.is_watertight or not mesh.is_winding_consistent:
        return False
    normals = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    if _signed_volume(mesh) < 0:
        normals = -normals
    lengths = np.linalg.norm(normals, axis=1)
    keep = lengths > 1e-15
    if not keep.any():
        return False
    normals = normals[keep] / lengths[keep, None]
    offsets = np.einsum("ij,ij->i", normals, v[f[keep, 0]])
    return bool(np.all(v @ normals.T - offsets[None, :] <= eps * max(1.0, float(np.abs(v).max()))))


def split_convex(vertices: np.ndarray, faces: np.ndarray, *, tolerance: float = 0.002) -> ConvexSplit:
    """Split a mesh into exact convex parts and concave pieces for CoACD.

    Pieces are the groups of faces joined through (welded) vertices. A convex solid piece is its own
    hull; a flat piece (thinner than MIN_THICKNESS) that is convex in its plane is its padded hull; a piece made of convex solids
    that only touch at vertices (boxes sharing corners, with their own vertices in the file) is those
    solids; anything else is concave.
    """
    raw_v = np.asarray(vertices, dtype=np.float64)
    raw_f = np.asarray(faces, dtype=np.int64)
    v, f = weld(raw_v, raw_f)
    parts: list[ConvexPart] = []
    concave: list[tuple[np.ndarray, np.ndarray]] = []
    for idx in face_components(f, len(v)):
        piece_v, piece_f = weld(*_compact(v, f[idx]))
        if is_convex_solid(piece_v, piece_f, tolerance=tolerance) or _is_flat_convex(piece_v, piece_f):
            parts.append(hull_part(piece_v))
            continue
        sub_v, sub_f = _compact(raw_v, raw_f[idx])
        sub = [weld(*_compact(sub_v, sub_f[s])) for s in face_components(sub_f, len(sub_v))]
        if len(sub) > 1 and all(is_convex_solid(sv, sf, tolerance=tolerance) for sv, sf in sub):
            parts.extend(hull_part(sv) for sv, _ in sub)
        else:
            concave.append((piece_v, piece_f))
    return ConvexSplit(parts, concave)


def _compact(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Only the vertices the faces use, in their original order (so weld() of the result equals weld() of the
    whole array with these faces, at the cost of the piece instead of the mesh)."""
    used, inverse = np.unique(faces, return_inverse=True)
    return vertices[used], inverse.reshape(-1, 3)


def _is_flat_convex(vertices: np.ndarray, faces: np.ndarray) -> bool:
    """Thinner than MIN_THICKNESS along some direction (a sheet, a line or a point) and convex in its plane: no
    point of its outline's hull farther than FLAT_BRIDGE from the sheet. (A grand piano's lid, a flat sheet with
    a curved notch, was once taken as its hull: 13 cm past the piano in the agent band.)"""
    import shapely

    directions, extents = _principal_extents(vertices)
    if extents[-1] >= MIN_THICKNESS:
        return False
    flat = (vertices - vertices.mean(axis=0)) @ directions[:2].T  # [V, 2] in the sheet's plane
    hull = shapely.MultiPoint(flat).convex_hull
    if hull.area <= 0:  # a line or a point: nothing to bridge
        return True
    sheet = shapely.union_all(shapely.polygons(flat[faces]))
    bridged = hull.difference(sheet.buffer(1e-9))
    if bridged.is_empty:
        return True
    probe = shapely.points(shapely.get_coordinates(shapely.segmentize(bridged, FLAT_BRIDGE / 2)))
    return bool(shapely.distance(probe, sheet).max() <= FLAT_BRIDGE)


def merge_parts(parts: list[ConvexPart], budget: int, band: tuple[float, float] | None = None,
                off_band: float = 0.02, reach: Callable[[ConvexPart], float] | None = None, tolerance: float = 0.0,
                max_checks: int = 256) -> list[ConvexPart]:
    """At most `budget` parts: repeatedly replace the two parts whose bounding boxes together enclose the least
    extra space by the hull of both (small neighbours first: two legs of a chair before a leg and the seat).
    Space outside the agent `band` (z range) counts `off_band` times as much: merging above it costs little.

    With `reach` (how far a part's band footprint lies past the source's, m), a pair is merged only when its
    hull reaches no farther than `tolerance` or than either part already did: the bounding boxes alone
    bridged a bed's notches by 3 cm. Where up to `max_checks` pairs in a row fail, the one reaching least
    far of them is merged."""
    out: list[ConvexPart | None] = list(parts)
    n = len(out)
    lo = np.array([p.vertices.min(axis=0) for p in parts]).reshape(-1, 3)
    hi = np.array([p.vertices.max(axis=0) for p in parts]).reshape(-1, 3)
    allowed = np.full(n, tolerance)
    if reach is not None:
        allowed = np.maximum(allowed, [reach(p) for p in parts])

    def wvol(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        height = b[..., 2] - a[..., 2]
        if band is not None:
            inside = np.clip(np.minimum(b[..., 2], band[1]) - np.maximum(a[..., 2], band[0]), 0.0, None)
            height = inside + off_band * (height - inside)
        return (b[..., 0] - a[..., 0]) * (b[..., 1] - a[..., 1]) * height

    def pair_cost(i: int, others: np.ndarray) -> np.ndarray:
        ulo, uhi = np.minimum(lo[i], lo[others]), np.maximum(hi[i], hi[others])
        return wvol(ulo, uhi) - wvol(lo[i], hi[i]) - wvol(lo[others], hi[others])

    cost = np.full((n, n), np.inf)  # [i, j], i < j; inf once merged away or found to reach too far
    for i in range(n - 1):
        cost[i, i + 1:] = pair_cost(i, np.arange(i + 1, n))
    alive = np.ones(n, dtype=bool)
    failed: dict[tuple[int, int], tuple[float, float]] = {}  # pair -> (reach past what it may, cost)
    for _ in range(n - budget):
        for _check in range(max_checks):
            i, j = (int(k) for k in np.unravel_index(np.argmin(cost), cost.shape))
            if not np.isfinite(cost[i, j]):
                break
            merged = hull_part(np.concatenate([out[i].vertices, out[j].vertices]))
            far = 0.0 if reach is None else reach(merged)
            if far <= max(allowed[i], allowed[j]) + 1e-9:
                break
            failed[i, j] = (far - max(allowed[i], allowed[j]), cost[i, j])
            cost[i, j] = np.inf
        else:
            i = -1
        if i < 0 or not np.isfinite(cost[i, j]):  # no pair fits within the checks: the one reaching least far
            i, j = min(failed, key=lambda k: (*failed[k], k))
            merged = hull_part(np.concatenate([out[i].vertices, out[j].vertices]))
            far = reach(merged)
        out[i], out[j], alive[j] = merged, None, False
        lo[i], hi[i] = merged.vertices.min(axis=0), merged.vertices.max(axis=0)
        allowed[i] = max(allowed[i], allowed[j], far)
        failed = {k: v for k, v in failed.items() if i not in k and j not in k}
        cost[j, :] = cost[:, j] = np.inf
        others = np.flatnonzero(alive & (np.arange(n) != i))
        row = pair_cost(i, others)
        cost[others[others < i], i] = row[others < i]
        cost[i, others[others > i]] = row[others > i]
    return [p for p in out if p is not None]
