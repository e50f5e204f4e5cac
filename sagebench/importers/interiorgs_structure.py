"""InteriorGS's floor plan as sagebench geometry: walls with their openings cut, floor and ceiling slabs per
room, room types in sagebench's words, and a door leaf's closed pose and state from its labelled box.

Choices where the dataset card is silent: a wall's `location` is its centre line (the QA pipelines built on
InteriorGS read it so), extended by half its thickness at both ends so that walls meeting at a corner close
it; an opening cuts its wall over the horizontal and vertical range of its outline (openings are rectangles
in practice); the floor is z = 0 (the card: wall heights are "from ground (z=0)").
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

import numpy as np
import shapely
import trimesh

from sagebench.importers.boxes import OrientedBox
from sagebench.importers.interiorgs_files import Hole, RoomOutline, WallSegment

SLAB_M = 0.05  # floor and ceiling slab thickness
DEFAULT_CEILING_M = 2.8  # ceiling height of a plan without walls
HOLE_REACH_M = 0.05  # an opening lies on a wall when its centre is within half the wall's thickness plus this
CLOSED_MAX_DEG = 10.0  # a leaf turned less than this from its opening is closed
OPEN_MIN_DEG = 60.0  # ... at least this much is open, in between ajar

# words in InteriorGS's room types (e.g. "Living and Dining Room", "Master Bedroom") -> sagebench's room type;
# the first rule whose word the type contains wins; a type matching none is kept, in snake_case
ROOM_RULES: tuple[tuple[str, str], ...] = (
    ("bedroom", "bedroom"), ("living", "living_room"), ("lounge", "living_room"), ("kitchen", "kitchen"),
    ("dining", "dining_room"), ("bath", "bathroom"), ("toilet", "bathroom"), ("washroom", "bathroom"),
    ("restroom", "bathroom"), ("lavatory", "bathroom"), ("study", "study"), ("library", "library"),
    ("office", "office"), ("balcony", "balcony"), ("corridor", "corridor"), ("hallway", "hallway"),
    ("aisle", "corridor"), ("foyer", "foyer"), ("entrance", "entrance"), ("storage", "storage_room"),
    ("laundry", "laundry_room"), ("garage", "garage"), ("gym", "gym"), ("nursery", "nursery"),
    ("cloak", "closet_room"), ("closet", "closet_room"),
)


def snake(text: str) -> str:
    """"Multi person sofa" -> "multi_person_sofa": lower case, runs of other characters as one underscore."""
    return re.sub(r"[^a-z0-9]+", "_", text.lower()).strip("_")


def room_type(interiorgs_type: str) -> str:
    """sagebench's room type for an InteriorGS `room_type` ("room" when it is empty)."""
    words = interiorgs_type.lower()
    for word, kind in ROOM_RULES:
        if word in words:
            return kind
    return snake(interiorgs_type) or "room"


def room_polygon(room: RoomOutline) -> shapely.Polygon:
    pts = room.profile
    if len(pts) > 3 and np.allclose(pts[0], pts[-1]):
        pts = pts[:-1]
    return shapely.Polygon(pts)


def slab(poly: shapely.Polygon, z0: float, z1: float) -> trimesh.Trimesh:
    """A prism over `poly` (xy, m) from z0 to z1 (shapely's constrained Delaunay triangulation of the outline)."""
    tris = shapely.get_coordinates(shapely.get_parts(shapely.constrained_delaunay_triangles(poly)))
    vertices, faces = np.unique(tris.reshape(-1, 4, 2)[:, :3].reshape(-1, 2), axis=0, return_inverse=True)
    mesh = trimesh.creation.extrude_triangulation(vertices, faces.reshape(-1, 3), z1 - z0)
    mesh.apply_translation((0.0, 0.0, z0))
    return mesh


def box_mesh(box: OrientedBox) -> trimesh.Trimesh:
    matrix = np.eye(4)
    matrix[:3, :3] = box.axes.T
    matrix[:3, 3] = box.centre
    return trimesh.creation.box(extents=2 * box.half, transform=matrix)


@dataclass(frozen=True)
class Opening:
    hole: int  # index into structure.json's holes
    s0: float  # along the wall from its first end, m
    s1: float
    z0: float
    z1: float


def wall_frame(wall: WallSegment) -> tuple[np.ndarray, np.ndarray, float]:
    """The wall's unit direction u [2] and normal n [2] (u turned +90 degrees) and length, m."""
    d = wall.b - wall.a
    length = float(np.linalg.norm(d))
    u = d / length if length > 0 else np.array([1.0, 0.0])
    return u, np.array([-u[1], u[0]]), length


def openings_on(wall: WallSegment, holes: tuple[Hole, ...], taken: set[int]) -> list[Opening]:
    """The holes not yet `taken` whose centre lies on this wall (within its thickness), as ranges along it."""
    u, n, length = wall_frame(wall)
    out = []
    for k, hole in enumerate(holes):
        if k in taken:
            continue
        rel = hole.profile[:, :2] - wall.a
        s, across = rel @ u, rel @ n
        centre_s, centre_n = (s.min() + s.max()) / 2, (across.min() + across.max()) / 2
        if abs(centre_n) > wall.thickness / 2 + HOLE_REACH_M or not -wall.thickness / 2 <= centre_s <= length + wall.thickness / 2:
            continue
        out.append(Opening(k, float(s.min()), float(s.max()), float(hole.profile[:, 2].min()),
                           float(hole.profile[:, 2].max())))
    return out


def wall_pieces(wall: WallSegment, openings: list[Opening]) -> list[OrientedBox]:
    """The solid boxes of a wall with its openings cut out: its extent is split where an opening starts or ends,
    and each span keeps what no opening covers between the floor and the wall's top."""
    u, n, length = wall_frame(wall)
    s_lo, s_hi = -wall.thickness / 2, length + wall.thickness / 2
    cuts = sorted({s_lo, s_hi, *(min(max(v, s_lo), s_hi) for o in openings for v in (o.s0, o.s1))})
    spans: list[tuple[float, float, tuple[tuple[float, float], ...]]] = []
    for a, b in zip(cuts[:-1], cuts[1:]):
        if b - a < 1e-6:
            continue
        mid = (a + b) / 2
        gaps = sorted((max(o.z0, 0.0), min(o.z1, wall.height)) for o in openings if o.s0 <= mid <= o.s1)
        solid, z = [], 0.0
        for g0, g1 in gaps:
            if g0 > z + 1e-6:
                solid.append((z, g0))
            z = max(z, g1)
        if wall.height > z + 1e-6:
            solid.append((z, wall.height))
        if spans and spans[-1][2] == tuple(solid) and abs(spans[-1][1] - a) < 1e-9:
            spans[-1] = (spans[-1][0], b, tuple(solid))  # same section as the span before: one box
        else:
            spans.append((a, b, tuple(solid)))
    axes = np.array([[u[0], u[1], 0.0], [n[0], n[1], 0.0], [0.0, 0.0, 1.0]])
    boxes = []
    for a, b, solid in spans:
        for z0, z1 in solid:
            centre = np.array([*(wall.a + u * (a + b) / 2), (z0 + z1) / 2])
            boxes.append(OrientedBox(centre, axes, np.array([(b - a) / 2, wall.thickness / 2, (z1 - z0) / 2])))
    return boxes


@dataclass(frozen=True)
class DoorPose:
    """A door leaf's state as sagebench's Door takes it: a closed leaf turns `swing * angle_deg` about `hinge`."""

    state: str  # open, ajar or closed
    hinge: tuple[float, float, float]
    swing: int
    angle_deg: float

    def closing(self) -> np.ndarray:
        """[4, 4] the rotation that takes the leaf as it stands back to its closed pose."""
        return trimesh.transformations.rotation_matrix(-math.radians(self.swing * self.angle_deg), [0, 0, 1],
                                                       point=self.hinge)


def door_pose(leaf: OrientedBox, wall: WallSegment, opening: Opening) -> DoorPose:
    """The state of the leaf `leaf` (its labelled box, as it stands) in `opening` of `wall`.

    The leaf's long horizontal axis against the wall's direction gives the angle. Its hinge is the end of the
    opening nearest the leaf's end that stays at the wall; the sign of the turn from the closed direction (hinge
    towards the opening's other end) to the leaf's direction (hinge towards its far end) gives the swing.
    """
    u, n, _ = wall_frame(wall)
    long_axis = int(np.argmax(leaf.half[:2]))
    d = leaf.axes[long_axis, :2] / max(np.linalg.norm(leaf.axes[long_axis, :2]), 1e-12)
    ends = [leaf.centre[:2] + sign * d * leaf.half[long_axis] for sign in (1.0, -1.0)]
    near, far = sorted(ends, key=lambda p: abs(float((p - wall.a) @ n)))
    e0, e1 = wall.a + u * opening.s0, wall.a + u * opening.s1
    hinge, other = (e0, e1) if np.linalg.norm(near - e0) <= np.linalg.norm(near - e1) else (e1, e0)
    closed_dir = (other - hinge) / max(np.linalg.norm(other - hinge), 1e-12)
    open_dir = far - hinge
    turn = math.degrees(math.atan2(closed_dir[0] * open_dir[1] - closed_dir[1] * open_dir[0], closed_dir @ open_dir))
    angle = abs(turn)
    hinge3 = (float(hinge[0]), float(hinge[1]), 0.0)
    if angle < CLOSED_MAX_DEG:
        return DoorPose("closed", hinge3, 1, 0.0)
    return DoorPose("open" if angle >= OPEN_MIN_DEG else "ajar", hinge3, 1 if turn > 0 else -1, round(angle, 3))
