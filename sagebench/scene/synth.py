"""`synth-scene`: a procedural apartment written in the artist-scene input format.

A 3 x 2 grid of cells with seeded sizes; two neighbouring cells merge into the living room.
Doors on a random spanning tree of the room graph are open, the remaining shared walls get an
ajar or closed door, and the front door is closed. Furniture is placed against walls or in groups,
never overlapping, keeping door swings clear and the floor connected for the default agent (AgentConfig).
"""

from __future__ import annotations

import hashlib
import json
import math
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import trimesh
from scipy import ndimage
from shapely import affinity
from shapely.geometry import Polygon, box as rect

from sagebench.errors import ConfigError
from sagebench.fileio import dumps_json, staged_dir, write_bytes
from sagebench.input_files import read_regular
from sagebench.scene import assets
from sagebench.scene.furniture import CATEGORY_NOUNS, Catalogue, CatalogueEntry
from sagebench.scene.loader import SCENE_FILE, yaw_quaternion
from sagebench.scene.model import Door, Room, SceneObject, SceneSpec, Transform
from sagebench.settings.shared import AgentConfig

WALL_T = 0.1  # wall thickness, m
CEILING = 2.7  # m
SYNTH_LICENSE = "apache-2.0"  # sagebench's: the procedural scenes are its output
SLOT_SLACK = 0.25  # a catalogue model may be this much wider or deeper than the slot it takes
DOOR_W = 1.0  # opening width, m
DOOR_H = 2.1  # opening height, m
LEAF_W, LEAF_T, LEAF_H = 0.95, 0.04, 2.05
CLEAR = 1.1  # side of the square kept free on both sides of a door, m
ROBOT_R = AgentConfig().radius  # the connectivity check's robot: the default agent, m
GRID = 0.05  # the connectivity check's cell size, m

ROOM_PROGRAMS: dict[str, list[str]] = {
    "living_room": ["sofa_group", "tv_group", "armchair", "armchair", "bookshelf", "plant", "floor_lamp", "ceiling_lamp"],
    "kitchen": ["dining_group", "counter", "fridge", "stove", "trash_bin", "plant", "ceiling_lamp"],
    "bedroom": ["bed_group", "wardrobe", "desk_group", "rug", "plant", "ceiling_lamp"],
    "study": ["desk_group", "bookshelf", "bookshelf", "armchair", "floor_lamp", "plant", "ceiling_lamp"],
    "bathroom": ["bathtub", "toilet", "sink", "washing_machine", "trash_bin", "ceiling_lamp"],
}


@dataclass
class _Room:
    id: str
    type: str
    rect: tuple[float, float, float, float]  # interior x0, y0, x1, y1

    @property
    def poly(self) -> Polygon:
        return rect(*self.rect)


@dataclass
class _Item:
    category: str
    footprint: Polygon  # world, for overlap tests
    xy: tuple[float, float]
    yaw: float
    z: float = 0.0
    size: tuple[float, float, float] | None = None


@dataclass
class _Layout:
    rooms: list[_Room]
    walls: list[trimesh.Trimesh] = field(default_factory=list)
    doors: list[tuple[tuple[float, float], float, str, int, str | None]] = field(default_factory=list)
    windows: list[tuple[tuple[float, float], float, str]] = field(default_factory=list)
    clear_zones: list[Polygon] = field(default_factory=list)


def synth_spec_and_meshes(seed: int, furniture: Catalogue | None = None) -> tuple[SceneSpec, dict[str, bytes]]:
    """The demo scene for `seed`: its spec and mesh files (relative path -> bytes).

    With a `furniture` catalogue, each piece whose category and slot some catalogue entry fits (by its name's
    head noun and size, entries taken in turn) is that entry's model at its catalogue size, its bottom at the
    entry's elevation, instead of the procedural piece; the layout is the same.
    """
    if seed < 0:
        raise ConfigError(f"must be 0 or more (got {seed})", field="--seed")
    rng = np.random.default_rng(seed)
    pick = _FurniturePicker(furniture) if furniture is not None else None
    layout = _layout(rng)
    files: dict[str, bytes] = {}
    objects: list[SceneObject] = []

    def add(category: str, kind: str, mesh: trimesh.Trimesh, ext: str, transform: Transform, **extra) -> None:
        data = _export(mesh, ext)
        name = f"meshes/{category}-{hashlib.sha256(data).hexdigest()[:12]}.{ext}"
        files[name] = data
        objects.append(SceneObject(instance_id=len(objects) + 1, category=category, kind=kind, mesh=name,
                                   transform=transform, **extra))

    for i, wall in enumerate(layout.walls):
        add("wall", "wall", wall, "ply", Transform(), attributes={"colour": "white", "material": "plaster"})
    for room in layout.rooms:
        x0, y0, x1, y1 = room.rect
        floor = assets.box((x1 - x0, y1 - y0, 0.05), ((x0 + x1) / 2, (y0 + y1) / 2, -0.025), assets.COLOURS["beige"])
        add("floor", "floor", floor, "ply", Transform(), room_id=room.id, attributes={"material": "wood"})
        ceil = assets.box((x1 - x0, y1 - y0, 0.05), ((x0 + x1) / 2, (y0 + y1) / 2, CEILING + 0.025), (245, 245, 245))
        add("ceiling", "ceiling", ceil, "ply", Transform(), room_id=room.id, attributes={"colour": "white"})
    for (cx, cy), yaw, state, swing, room_id in layout.doors:
        leaf = assets.box((LEAF_W, LEAF_T, LEAF_H), (0, 0, LEAF_H / 2), assets.COLOURS["brown"])
        hinge_local = np.array([-LEAF_W / 2, 0.0])
        c, s = math.cos(yaw), math.sin(yaw)
        hinge = (cx + c * hinge_local[0], cy + s * hinge_local[0], 0.0)
        door = Door(state=state, hinge=_r3(hinge), swing=swing)
        add("door", "door", leaf, "ply", Transform(translation=_r3((cx, cy, 0.0)), rotation_wxyz=yaw_quaternion(yaw)),
            room_id=room_id, door=door, attributes={"material": "wood", "colour": "brown"})
    for (cx, cy), yaw, room_id in layout.windows:
        pane = assets.box((1.2, 0.04, 1.2), (0, 0, 1.5), (180, 210, 230))
        add("window", "window", pane, "glb", Transform(translation=_r3((cx, cy, 0.0)), rotation_wxyz=yaw_quaternion(yaw)),
            room_id=room_id, attributes={"material": "glass"})
    for room in layout.rooms:
        for item, colour, material in _furnish(room, layout, rng):
            transform = Transform(translation=_r3((*item.xy, item.z)), rotation_wxyz=yaw_quaternion(item.yaw))
            entry = None if pick is None else pick(item)
            if entry is not None:
                placed = Transform(translation=_r3((*item.xy, item.z + entry.elevation_m)),
                                   rotation_wxyz=transform.rotation_wxyz)
                add(item.category, "object", pick.model(entry), "glb", placed, room_id=room.id,
                    attributes={"asset": entry.id})
                continue
            asset = assets.CATALOGUE[item.category]
            mesh = asset.build(*item.size, assets.COLOURS[colour])
            add(item.category, "object", mesh, asset.ext, transform, room_id=room.id,
                attributes={"colour": colour, "material": material})

    rooms = [Room(id=r.id, type=r.type, polygon=[_r2(p) for p in r.poly.exterior.coords[:-1]]) for r in layout.rooms]
    spec = SceneSpec(scene_id=f"demo_apartment_{seed}", units="m", up_axis="Z", floor_height=0.0,
                     rooms=rooms, objects=objects, license=_license(pick))
    return spec, files


class _FurniturePicker:
    """Catalogue entries for placed items, each at its catalogue size and elevation as Sweet Home 3D places
    it: among the entries naming a category and fitting the item's slot (up to SLOT_SLACK wider or deeper,
    under the ceiling), one in turn (turns shared between categories with the same nouns, so a scene shows as
    many different models as the catalogue has); None where no entry fits, and the procedural piece stays."""

    def __init__(self, catalogue: Catalogue):
        self.catalogue = catalogue
        self.turn: dict[frozenset[str], int] = {}
        self.models: dict[int, trimesh.Trimesh] = {}
        self.used = False  # some entry was picked

    def __call__(self, item: _Item) -> CatalogueEntry | None:
        entries = [e for e in self.catalogue.matching(item.category)
                   if item.size is not None and e.fits(item.size, CEILING - 0.1 - item.z, SLOT_SLACK)]
        if not entries:
            return None
        key = CATEGORY_NOUNS[item.category]
        k = self.turn.get(key, 0)
        self.turn[key] = k + 1
        self.used = True
        return entries[k % len(entries)]

    def model(self, entry: CatalogueEntry) -> trimesh.Trimesh:
        """The entry's mesh at its catalogue size, standing on z = 0 (loaded once)."""
        if entry.number not in self.models:
            self.models[entry.number] = self.catalogue.load_model(entry)
        return self.models[entry.number]


def _license(pick: _FurniturePicker | None) -> str:
    """The procedural scene is sagebench's, under its own licence (apache-2.0); catalogue models in the public
    domain (Sweet Home 3D's `license=Public domain`, CC0) add no terms, any other licence makes it `other`."""
    if pick is None or not pick.used:
        return SYNTH_LICENSE
    return SYNTH_LICENSE if pick.catalogue.public_domain else "other"


def write_synth_scene(out: Path, *, seed: int = 0, furniture: Path | None = None, force: bool = False) -> SceneSpec:
    """Write the demo scene for `seed` into `out` (replaced whole, atomically), furnished from the Sweet Home
    3D catalogue `furniture` (a directory or .sh3f) where given. The caller claims `out` first (synth-scene and
    demo: run_folder.check_scene_out with `is_synth_scene`); with `force` the user's hidden files in it are not
    carried over."""
    spec, files = synth_spec_and_meshes(seed, None if furniture is None else Catalogue(furniture))
    with staged_dir(Path(out), keep_hidden=not force) as tmp:  # --force replaces OUT whatever it holds
        for name, data in files.items():
            write_bytes(tmp / name, data)
        write_bytes(tmp / SCENE_FILE, dumps_json(spec.model_dump(mode="json", exclude_defaults=True)).encode())
    return spec


def is_synth_scene(out: Path) -> bool:
    """Whether `out` holds exactly what write_synth_scene writes (scene.json of a demo apartment and the meshes
    it names, nothing else)."""
    try:
        spec = json.loads(read_regular(Path(out) / SCENE_FILE, limit=1 << 26) or b"")  # a FIFO is never opened
        scene_id, meshes = spec.get("scene_id"), {o["mesh"] for o in spec.get("objects")}
    except (OSError, ValueError, AttributeError, TypeError, KeyError):
        return False
    present = {p.relative_to(out).as_posix() for p in out.rglob("*") if not p.is_dir() or p.is_symlink()}
    return (isinstance(scene_id, str) and re.fullmatch(r"demo_apartment_\d+", scene_id) is not None
            and {p.name for p in out.iterdir()} == {SCENE_FILE, "meshes"} and present == meshes | {SCENE_FILE})


def _export(mesh: trimesh.Trimesh, ext: str) -> bytes:
    data = mesh.export(file_type=ext)
    return data.encode() if isinstance(data, str) else bytes(data)


def _r2(p) -> tuple[float, float]:
    return (round(float(p[0]), 4), round(float(p[1]), 4))


def _r3(p) -> tuple[float, float, float]:
    return (round(float(p[0]), 4), round(float(p[1]), 4), round(float(p[2]), 4))


# ---------------------------------------------------------------- layout


def _layout(rng: np.random.Generator) -> _Layout:
    xs = np.concatenate([[0.0], np.cumsum(np.round(rng.uniform(3.4, 4.8, 3), 1))])
    ys = np.concatenate([[0.0], np.cumsum(np.round(rng.uniform(3.4, 4.6, 2), 1))])
    cells = {(i, j): (xs[i], ys[j], xs[i + 1], ys[j + 1]) for i in range(3) for j in range(2)}
    merge_row, merge_col = int(rng.integers(2)), int(rng.integers(2))
    merged = {(merge_col, merge_row), (merge_col + 1, merge_row)}
    owner: dict[tuple[int, int], int] = {}
    bounds: list[tuple[float, float, float, float]] = []
    for cell in sorted(merged):
        owner[cell] = 0
    a, b = cells[(merge_col, merge_row)], cells[(merge_col + 1, merge_row)]
    bounds.append((a[0], a[1], b[2], b[3]))
    for cell in sorted(cells):
        if cell not in owner:
            owner[cell] = len(bounds)
            bounds.append(cells[cell])
    # types: merged cell is the living room, the smallest other cell the bathroom
    others = sorted(range(1, len(bounds)), key=lambda k: ((bounds[k][2] - bounds[k][0]) * (bounds[k][3] - bounds[k][1]), k))
    kinds = ["kitchen", "bedroom", "study"]
    rng.shuffle(kinds)
    types = {0: "living_room", others[0]: "bathroom"} | dict(zip(others[1:], kinds))
    h = WALL_T / 2
    rooms = [_Room(f"room_{k}", types[k], (x0 + h, y0 + h, x1 - h, y1 - h)) for k, (x0, y0, x1, y1) in enumerate(bounds)]
    layout = _Layout(rooms=rooms)

    # wall segments between cells: (p0, p1, room_a, room_b or None for exterior)
    segs: list[tuple[tuple[float, float], tuple[float, float], int, int | None]] = []
    for (i, j), (x0, y0, x1, y1) in sorted(cells.items()):
        right = owner.get((i + 1, j))
        top = owner.get((i, j + 1))
        if right is None:
            segs.append(((x1, y0), (x1, y1), owner[(i, j)], None))
        elif right != owner[(i, j)]:
            segs.append(((x1, y0), (x1, y1), owner[(i, j)], right))
        if top is None:
            segs.append(((x0, y1), (x1, y1), owner[(i, j)], None))
        elif top != owner[(i, j)]:
            segs.append(((x0, y1), (x1, y1), owner[(i, j)], top))
        if i == 0:
            segs.append(((x0, y0), (x0, y1), owner[(i, j)], None))
        if j == 0:
            segs.append(((x0, y0), (x1, y0), owner[(i, j)], None))

    # one door per pair of neighbouring rooms; a seeded spanning tree of them open
    pairs: dict[tuple[int, int], int] = {}
    for k, (_, _, ra, rb) in enumerate(segs):
        if rb is not None:
            pairs.setdefault((min(ra, rb), max(ra, rb)), k)
    order = list(pairs)
    rng.shuffle(order)
    parent = list(range(len(bounds)))

    def find(u: int) -> int:
        while parent[u] != u:
            u = parent[u]
        return u

    door_state: dict[int, str] = {}
    for pair in order:
        ra, rb = find(pair[0]), find(pair[1])
        if ra != rb:
            parent[ra] = rb
            door_state[pairs[pair]] = "open"
        else:
            door_state[pairs[pair]] = "ajar" if not any(s == "ajar" for s in door_state.values()) else str(rng.choice(["ajar", "closed"]))
    exterior = [k for k, s in enumerate(segs) if s[3] is None and s[2] == 0]
    door_state[exterior[int(rng.integers(len(exterior)))]] = "closed"
    windows = {k for k, s in enumerate(segs) if s[3] is None and k not in door_state and rng.random() < 0.6}

    for k, (p0, p1, ra, rb) in enumerate(segs):
        length = math.dist(p0, p1)
        ux, uy = (p1[0] - p0[0]) / length, (p1[1] - p0[1]) / length
        yaw = math.atan2(uy, ux)
        openings: list[tuple[float, float]] = []
        if k in door_state:
            t = float(np.round(rng.uniform(0.5 + DOOR_W / 2, length - 0.5 - DOOR_W / 2), 2))
            openings.append((t - DOOR_W / 2, t + DOOR_W / 2))
            centre = (p0[0] + ux * t, p0[1] + uy * t)
            swing = int(rng.choice([1, -1]))
            # the leaf swings into the room on its left (swing +1) or right (-1) of the wall direction
            into = ra if (swing == 1) == _left_of(rooms[ra], p0, (ux, uy)) else (rb if rb is not None else ra)
            layout.doors.append((centre, yaw, door_state[k], swing, rooms[into].id))
            for side in (1, -1):
                nx, ny = -uy * side, ux * side
                zone = rect(-CLEAR / 2, 0, CLEAR / 2, CLEAR)
                zone = affinity.rotate(zone, math.degrees(math.atan2(ny, nx)) - 90, origin=(0, 0))
                layout.clear_zones.append(affinity.translate(zone, centre[0], centre[1]))
        elif k in windows:
            t = length / 2
            layout.windows.append(((p0[0] + ux * t, p0[1] + uy * t), yaw, rooms[ra].id))
        layout.walls.append(_wall_mesh(p0, (ux, uy), length, openings))
    return layout


def _left_of(room: _Room, p0: tuple[float, float], u: tuple[float, float]) -> bool:
    c = room.poly.centroid
    return (u[0] * (c.y - p0[1]) - u[1] * (c.x - p0[0])) > 0


def _wall_mesh(p0, u, length: float, openings: list[tuple[float, float]]) -> trimesh.Trimesh:
    """A straight wall with door openings (a lintel above each), authored in world coordinates."""
    pieces: list[tuple[float, float, float, float]] = []  # t0, t1, z0, z1
    t = -WALL_T / 2
    for a, b in openings:
        pieces.append((t, a, 0.0, CEILING))
        pieces.append((a, b, DOOR_H, CEILING))
        t = b
    pieces.append((t, length + WALL_T / 2, 0.0, CEILING))
    yaw = math.atan2(u[1], u[0])
    parts = []
    for t0, t1, z0, z1 in pieces:
        if t1 - t0 < 1e-6:
            continue
        m = assets.box((t1 - t0, WALL_T, z1 - z0), ((t0 + t1) / 2, 0, (z0 + z1) / 2), assets.COLOURS["white"])
        m.apply_transform(trimesh.transformations.rotation_matrix(yaw, [0, 0, 1]))
        m.apply_translation((p0[0], p0[1], 0))
        parts.append(m)
    return trimesh.util.concatenate(parts)


# ---------------------------------------------------------------- furniture


def _furnish(room: _Room, layout: _Layout, rng: np.random.Generator):
    """Yield (item, colour, material) for one room, placed by its program."""
    placed: list[_Item] = []
    keep_out = [z for z in layout.clear_zones if z.intersects(room.poly)]
    used_colours: dict[str, list[str]] = {}
    for entry in ROOM_PROGRAMS[room.type]:
        group = _place_entry(entry, room, placed, keep_out, layout, rng)
        for item in group:
            placed.append(item)
            asset = assets.CATALOGUE[item.category]
            colour = _pick_colour(item.category, asset.colours, used_colours, rng)
            yield item, colour, str(rng.choice(asset.materials))


def _pick_colour(category: str, options: tuple[str, ...], used: dict[str, list[str]], rng: np.random.Generator) -> str:
    """Repeat a colour now and then so that some objects differ only in another attribute or place."""
    prior = used.setdefault(category, [])
    if prior and len(options) > 1 and rng.random() < 0.5:
        colour = prior[-1]
    else:
        colour = str(rng.choice(options))
    prior.append(colour)
    return colour


def _sized(category: str, rng: np.random.Generator) -> tuple[float, float, float]:
    w, d, h = assets.CATALOGUE[category].size
    f = float(rng.uniform(0.92, 1.08))
    return (round(w * f, 3), round(d * f, 3), h)


def _place_entry(entry: str, room: _Room, placed: list[_Item], keep_out: list[Polygon], layout: _Layout,
                 rng: np.random.Generator) -> list[_Item]:
    for attempt in range(60):
        group = _propose(entry, room, rng, tight=attempt >= 30)
        if group and _fits(group, room, placed, keep_out) and _floor_connected(layout, room, placed + group):
            return group
    return []


def _propose(entry: str, room: _Room, rng: np.random.Generator, tight: bool) -> list[_Item]:
    """One candidate placement; `tight` asks for the smaller variant of a group after many misses."""
    x0, y0, x1, y1 = room.rect
    if entry == "ceiling_lamp":
        size = assets.CATALOGUE["ceiling_lamp"].size
        return [_item("ceiling_lamp", size, ((x0 + x1) / 2, (y0 + y1) / 2), 0.0)]
    if entry == "rug":
        size = _sized("rug", rng)
        xy = (float(rng.uniform(x0 + 1.2, x1 - 1.2)), float(rng.uniform(y0 + 1.0, y1 - 1.0)))
        return [_item("rug", size, xy, float(rng.choice([0.0, math.pi / 2])))]
    if entry == "dining_group":
        return _dining(room, rng, tight)
    if entry.endswith("_group"):
        return _wall_group(entry, room, rng)
    return [_against_wall(entry, _sized(entry, rng), room, rng)]


def _item(category: str, size: tuple[float, float, float], xy: tuple[float, float], yaw: float, z: float = 0.0) -> _Item:
    w, d, _ = size
    fp = affinity.rotate(rect(-w / 2, -d / 2, w / 2, d / 2), yaw, origin=(0, 0), use_radians=True)
    return _Item(category, affinity.translate(fp, *xy), (round(xy[0], 3), round(xy[1], 3)), yaw, z, size)


def _wall_frame(room: _Room, side: int, t: float, depth: float) -> tuple[tuple[float, float], float, tuple[float, float]]:
    """Point at fraction t along wall `side` (0 S, 1 E, 2 N, 3 W), `depth` into the room, and the yaw that
    turns an asset's back (+Y) to that wall; also the inward normal."""
    x0, y0, x1, y1 = room.rect
    if side == 0:
        return (x0 + t * (x1 - x0), y0 + depth), math.pi, (0.0, 1.0)
    if side == 1:
        return (x1 - depth, y0 + t * (y1 - y0)), -math.pi / 2, (-1.0, 0.0)
    if side == 2:
        return (x0 + t * (x1 - x0), y1 - depth), 0.0, (0.0, -1.0)
    return (x0 + depth, y0 + t * (y1 - y0)), math.pi / 2, (1.0, 0.0)


def _against_wall(category: str, size: tuple[float, float, float], room: _Room, rng: np.random.Generator,
                  side: int | None = None, t: float | None = None) -> _Item:
    side = int(rng.integers(4)) if side is None else side
    t = float(rng.uniform(0.1, 0.9)) if t is None else t
    xy, yaw, _ = _wall_frame(room, side, t, size[1] / 2 + 0.02)
    return _item(category, size, xy, yaw)


def _wall_group(entry: str, room: _Room, rng: np.random.Generator) -> list[_Item]:
    side, t = int(rng.integers(4)), float(rng.uniform(0.2, 0.8))
    if entry == "sofa_group":
        sofa = _against_wall("sofa", _sized("sofa", rng), room, rng, side, t)
        _, yaw, n = _wall_frame(room, side, t, 0)
        sw, sd, _ = sofa.size
        table_size = _sized("coffee_table", rng)
        # the table stands in front of the long seat, the chaise reaches past it on the asset's -X side
        off = sd / 2 + 0.35 + table_size[1] / 2
        along = (-n[1], n[0])
        tx = sofa.xy[0] + n[0] * off - along[0] * 0.25
        ty = sofa.xy[1] + n[1] * off - along[1] * 0.25
        table = _item("coffee_table", table_size, (tx, ty), yaw)
        rug = _item("rug", _sized("rug", rng), (tx, ty), yaw)
        return [sofa, table, rug]
    if entry == "tv_group":
        stand = _against_wall("tv_stand", _sized("tv_stand", rng), room, rng, side, t)
        tv = _item("tv", assets.CATALOGUE["tv"].size, stand.xy, stand.yaw, z=stand.size[2])
        return [stand, tv]
    if entry == "bed_group":
        bed = _against_wall("bed", _sized("bed", rng), room, rng, side, t)
        _, yaw, n = _wall_frame(room, side, t, 0)
        along = (-n[1], n[0])
        ns = assets.CATALOGUE["nightstand"].size
        items = [bed]
        back = (bed.xy[0] - n[0] * (bed.size[1] - ns[1]) / 2, bed.xy[1] - n[1] * (bed.size[1] - ns[1]) / 2)
        for sgn in (1, -1):
            off = bed.size[0] / 2 + 0.05 + ns[0] / 2
            items.append(_item("nightstand", ns, (back[0] + along[0] * off * sgn, back[1] + along[1] * off * sgn), yaw))
        return items
    if entry == "desk_group":
        desk = _against_wall("desk", _sized("desk", rng), room, rng, side, t)
        _, yaw, n = _wall_frame(room, side, t, 0)
        cs = assets.CATALOGUE["office_chair"].size
        off = desk.size[1] / 2 + 0.1 + cs[1] / 2
        chair = _item("office_chair", cs, (desk.xy[0] + n[0] * off, desk.xy[1] + n[1] * off), yaw + math.pi)
        return [desk, chair]
    raise ValueError(entry)


def _dining(room: _Room, rng: np.random.Generator, tight: bool) -> list[_Item]:
    """A free-standing table with chairs pulled out on its long sides, facing it (a table for two when tight)."""
    x0, y0, x1, y1 = room.rect
    size = (0.8, 0.8, 0.75) if tight else _sized("dining_table", rng)
    yaw = float(rng.choice([0.0, math.pi / 2]))
    cs = assets.CATALOGUE["chair"].size
    off = size[1] / 2 + 0.05 + cs[1] / 2
    half = np.array([size[0] / 2, off + cs[1] / 2]) + (0.05 if tight else 0.3)  # half-extent plus a walkway
    if yaw:
        half = half[::-1]
    if x1 - x0 < 2 * half[0] or y1 - y0 < 2 * half[1]:
        return []
    xy = (float(rng.uniform(x0 + half[0], x1 - half[0])), float(rng.uniform(y0 + half[1], y1 - half[1])))
    c, s = math.cos(yaw), math.sin(yaw)
    items = [_item("dining_table", size, xy, yaw)]
    for sgn in (1, -1):
        for along in (0.0,) if tight else (-size[0] / 4, size[0] / 4):
            px, py = along, sgn * off
            chair_yaw = yaw + (0.0 if sgn == 1 else math.pi)
            items.append(_item("chair", cs, (xy[0] + c * px - s * py, xy[1] + s * px + c * py), chair_yaw))
    return items


def _fits(group: list[_Item], room: _Room, placed: list[_Item], keep_out: list[Polygon]) -> bool:
    inner = room.poly.buffer(-0.01)
    for item in group:
        if not inner.contains(item.footprint):
            return False
        if item.category in assets.NON_BLOCKING:
            continue
        if any(item.footprint.intersects(z) for z in keep_out):
            return False
        for other in placed:
            if other.category not in assets.NON_BLOCKING and item.footprint.buffer(0.05).intersects(other.footprint):
                if not (item.category == "tv" and other.category == "tv_stand"):
                    return False
    return True


def _floor_connected(layout: _Layout, room: _Room, items: list[_Item]) -> bool:
    """Every door of this room stays reachable from every other for a robot of radius ROBOT_R."""
    x0, y0, x1, y1 = room.rect
    pad = CLEAR
    ox, oy = x0 - pad, y0 - pad
    shape = (int(math.ceil((y1 - y0 + 2 * pad) / GRID)), int(math.ceil((x1 - x0 + 2 * pad) / GRID)))
    yy, xx = np.mgrid[0 : shape[0], 0 : shape[1]]
    px, py = ox + (xx + 0.5) * GRID, oy + (yy + 0.5) * GRID
    inside = (px > x0) & (px < x1) & (py > y0) & (py < y1)
    zones = [z for z in layout.clear_zones if z.intersects(room.poly)]
    if len(zones) < 2:
        return True
    free = inside.copy()
    for z in zones:  # the door's own clearance reaches through the opening
        free |= _mask(z, px, py)
    for item in items:
        if item.category not in assets.NON_BLOCKING:
            free &= ~_mask(item.footprint, px, py)
    r = int(math.ceil(ROBOT_R / GRID))
    disk = (np.hypot(*np.mgrid[-r : r + 1, -r : r + 1]) <= r)
    walkable = ~ndimage.binary_dilation(~free, structure=disk)
    labels, _ = ndimage.label(walkable)
    ids = set()
    for z in zones:
        c = z.intersection(room.poly).centroid
        col, row = int((c.x - ox) / GRID), int((c.y - oy) / GRID)
        ids.add(int(labels[row, col]))
    return len(ids) == 1 and 0 not in ids


def _mask(poly: Polygon, px: np.ndarray, py: np.ndarray) -> np.ndarray:
    from shapely import contains_xy

    return contains_xy(poly, px, py)
