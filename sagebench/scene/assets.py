"""Procedural furniture meshes with real-world sizes, built from parts so footprints are not boxes.

Local frame of every asset: metres, Z up, footprint centred on the origin, standing on z = 0,
front facing -Y and back at +Y (the side that goes against a wall).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import trimesh

RGB = tuple[int, int, int]

COLOURS: dict[str, RGB] = {
    "red": (178, 34, 34),
    "blue": (40, 70, 160),
    "green": (46, 125, 50),
    "yellow": (230, 190, 40),
    "orange": (230, 120, 30),
    "white": (235, 235, 230),
    "black": (30, 30, 30),
    "grey": (128, 128, 128),
    "brown": (110, 70, 40),
    "beige": (215, 195, 160),
}
WOOD: RGB = (150, 105, 60)
METAL: RGB = (170, 170, 175)


def _paint(mesh: trimesh.Trimesh, rgb: RGB) -> trimesh.Trimesh:
    mesh.visual = trimesh.visual.ColorVisuals(mesh, vertex_colors=np.tile([*rgb, 255], (len(mesh.vertices), 1)))
    return mesh


def box(size: tuple[float, float, float], centre: tuple[float, float, float], rgb: RGB) -> trimesh.Trimesh:
    mesh = trimesh.creation.box(extents=size)
    mesh.apply_translation(centre)
    return _paint(mesh, rgb)


def cylinder(radius: float, z0: float, z1: float, xy: tuple[float, float], rgb: RGB, sections: int = 16) -> trimesh.Trimesh:
    mesh = trimesh.creation.cylinder(radius=radius, height=z1 - z0, sections=sections)
    mesh.apply_translation((xy[0], xy[1], (z0 + z1) / 2))
    return _paint(mesh, rgb)


def _join(parts: list[trimesh.Trimesh]) -> trimesh.Trimesh:
    return trimesh.util.concatenate(parts)


def table(w: float, d: float, h: float, rgb: RGB, leg: float = 0.05) -> trimesh.Trimesh:
    """A top on four legs: the 1.2 m band sees the top, a band below it only the legs."""
    top = 0.04
    parts = [box((w, d, top), (0, 0, h - top / 2), rgb)]
    for sx in (-1, 1):
        for sy in (-1, 1):
            parts.append(box((leg, leg, h - top), (sx * (w / 2 - leg), sy * (d / 2 - leg), (h - top) / 2), rgb))
    return _join(parts)


def chair(w: float, d: float, h: float, rgb: RGB) -> trimesh.Trimesh:
    seat_h, leg = 0.45, 0.04
    parts = [table(w, d, seat_h, rgb, leg=leg)]
    parts.append(box((w, 0.04, h - seat_h), (0, d / 2 - 0.02, seat_h + (h - seat_h) / 2), rgb))
    return _join(parts)


def office_chair(w: float, d: float, h: float, rgb: RGB) -> trimesh.Trimesh:
    caster = 0.035  # the base's casters stand it on the floor
    parts = [
        *(box((0.04, 0.04, caster), (x, y, caster / 2), METAL)
          for x, y in ((-(w / 2 - 0.02), 0), (w / 2 - 0.02, 0), (0, -(d / 2 - 0.02)), (0, d / 2 - 0.02))),
        box((w, 0.08, 0.03), (0, 0, 0.05), METAL),
        box((0.08, d, 0.03), (0, 0, 0.05), METAL),
        cylinder(0.03, 0.05, 0.42, (0, 0), METAL),
        box((w * 0.9, d * 0.9, 0.08), (0, 0, 0.46), rgb),
        box((w * 0.8, 0.06, h - 0.55), (0, d / 2 - 0.05, 0.5 + (h - 0.55) / 2), rgb),
    ]
    return _join(parts)


def cabinet(w: float, d: float, h: float, rgb: RGB) -> trimesh.Trimesh:
    """A closed body on a plinth (wardrobe, fridge, counter, nightstand, ...)."""
    plinth = min(0.08, h * 0.1)
    return _join([box((w * 0.96, d * 0.9, plinth), (0, 0.01, plinth / 2), (40, 40, 40)),
                  box((w, d, h - plinth), (0, 0, plinth + (h - plinth) / 2), rgb)])


def bookshelf(w: float, d: float, h: float, rgb: RGB) -> trimesh.Trimesh:
    t = 0.02
    parts = [box((t, d, h), (sx * (w / 2 - t / 2), 0, h / 2), rgb) for sx in (-1, 1)]
    parts.append(box((w, t, h), (0, d / 2 - t / 2, h / 2), rgb))
    for k in range(5):
        z = t / 2 + k * (h - t) / 4
        parts.append(box((w - 2 * t, d - t, t), (0, -t / 2, z), rgb))
    return _join(parts)


def sofa_l(w: float, d: float, h: float, rgb: RGB) -> trimesh.Trimesh:
    """An L-shaped sofa: a long seat along the back and a chaise on the -X side."""
    seat_d, seat_h, back_t = 0.9, 0.42, 0.2
    parts = [
        box((w, seat_d, seat_h), (0, d / 2 - seat_d / 2, seat_h / 2), rgb),
        box((seat_d, d - seat_d, seat_h), (-w / 2 + seat_d / 2, -seat_d / 2, seat_h / 2), rgb),
        box((w, back_t, h), (0, d / 2 - back_t / 2, h / 2), rgb),
        box((0.2, seat_d, 0.62), (w / 2 - 0.1, d / 2 - seat_d / 2, 0.31), rgb),
    ]
    return _join(parts)


def armchair(w: float, d: float, h: float, rgb: RGB) -> trimesh.Trimesh:
    arm = 0.15
    return _join([
        box((w, d, 0.42), (0, 0, 0.21), rgb),
        box((w, 0.18, h), (0, d / 2 - 0.09, h / 2), rgb),
        box((arm, d, 0.62), (-w / 2 + arm / 2, 0, 0.31), rgb),
        box((arm, d, 0.62), (w / 2 - arm / 2, 0, 0.31), rgb),
    ])


def bed(w: float, d: float, h: float, rgb: RGB) -> trimesh.Trimesh:
    return _join([
        table(w, d, 0.3, WOOD, leg=0.08),
        box((w - 0.05, d - 0.1, 0.22), (0, -0.03, 0.41), (240, 240, 240)),
        box((w, 0.08, h), (0, d / 2 - 0.04, h / 2), rgb),
    ])


def floor_lamp(w: float, d: float, h: float, rgb: RGB) -> trimesh.Trimesh:
    return _join([
        cylinder(w / 2 * 0.7, 0.0, 0.03, (0, 0), METAL),
        cylinder(0.015, 0.03, h - 0.3, (0, 0), METAL),
        cylinder(w / 2, h - 0.3, h, (0, 0), rgb),
    ])


def ceiling_lamp(w: float, d: float, h: float, rgb: RGB, ceiling: float = 2.7) -> trimesh.Trimesh:
    """Hangs from the ceiling: its lowest point is ceiling - h, far above the 1.2 m band."""
    shade = 0.25
    return _join([
        cylinder(0.01, ceiling - h + shade, ceiling, (0, 0), METAL, sections=8),
        cylinder(w / 2, ceiling - h, ceiling - h + shade, (0, 0), rgb),
    ])


def rug(w: float, d: float, h: float, rgb: RGB) -> trimesh.Trimesh:
    return box((w, d, h), (0, 0, h / 2), rgb)


def plant(w: float, d: float, h: float, rgb: RGB) -> trimesh.Trimesh:
    pot = cylinder(w * 0.3, 0.0, 0.35, (0, 0), rgb)
    leaves = trimesh.creation.icosphere(subdivisions=2, radius=w / 2)
    leaves.apply_scale((1.0, 1.0, (h - 0.35) / w))
    leaves.apply_translation((0, 0, 0.35 + (h - 0.35) / 2))
    return _join([pot, _paint(leaves, (60, 140, 60))])


def bin_(w: float, d: float, h: float, rgb: RGB) -> trimesh.Trimesh:
    return cylinder(w / 2, 0.0, h, (0, 0), rgb)


def stove(w: float, d: float, h: float, rgb: RGB) -> trimesh.Trimesh:
    parts = [cabinet(w, d, h, rgb)]
    for sx in (-1, 1):
        for sy in (-1, 1):
            parts.append(cylinder(0.08, h, h + 0.01, (sx * w / 4, sy * d / 4), (20, 20, 20)))
    return _join(parts)


def sink(w: float, d: float, h: float, rgb: RGB) -> trimesh.Trimesh:
    return _join([cabinet(w, d, h - 0.12, rgb), box((w * 0.7, d * 0.6, 0.12), (0, -0.02, h - 0.06), (245, 245, 245))])


def toilet(w: float, d: float, h: float, rgb: RGB) -> trimesh.Trimesh:
    return _join([
        cylinder(w / 2, 0.0, 0.42, (0, -d / 2 + w / 2), rgb),
        box((w * 0.9, 0.2, h - 0.05), (0, d / 2 - 0.1, (h - 0.05) / 2 + 0.05), rgb),
    ])


def bathtub(w: float, d: float, h: float, rgb: RGB) -> trimesh.Trimesh:
    t = 0.06
    return _join([
        box((w, d, t), (0, 0, t / 2), rgb),
        box((w, t, h), (0, d / 2 - t / 2, h / 2), rgb),
        box((w, t, h), (0, -d / 2 + t / 2, h / 2), rgb),
        box((t, d, h), (w / 2 - t / 2, 0, h / 2), rgb),
        box((t, d, h), (-w / 2 + t / 2, 0, h / 2), rgb),
    ])


def tv(w: float, d: float, h: float, rgb: RGB) -> trimesh.Trimesh:
    return _join([box((0.3, 0.2, 0.05), (0, 0, 0.025), (20, 20, 20)), box((w, d, h - 0.1), (0, 0, 0.1 + (h - 0.1) / 2), rgb)])


@dataclass(frozen=True)
class Asset:
    """How to build one furniture category: size (w, d, h) in metres, colours and materials to draw from."""

    build: Callable[..., trimesh.Trimesh]
    size: tuple[float, float, float]
    colours: tuple[str, ...]
    materials: tuple[str, ...]
    ext: str = "glb"


CATALOGUE: dict[str, Asset] = {
    "sofa": Asset(sofa_l, (2.3, 1.6, 0.85), ("grey", "blue", "beige", "green"), ("fabric", "leather")),
    "armchair": Asset(armchair, (0.85, 0.85, 0.85), ("red", "blue", "yellow", "grey", "green"), ("fabric", "leather")),
    "coffee_table": Asset(table, (1.1, 0.6, 0.45), ("brown", "white", "black"), ("wood", "glass")),
    "rug": Asset(rug, (2.0, 1.4, 0.01), ("red", "beige", "blue", "grey"), ("wool", "cotton")),
    "tv_stand": Asset(cabinet, (1.6, 0.42, 0.5), ("white", "black", "brown"), ("wood",)),
    "tv": Asset(tv, (1.2, 0.08, 0.75), ("black",), ("plastic",)),
    "bookshelf": Asset(bookshelf, (0.9, 0.35, 1.8), ("brown", "white", "black"), ("wood",)),
    "floor_lamp": Asset(floor_lamp, (0.4, 0.4, 1.6), ("white", "yellow", "black"), ("metal",)),
    "ceiling_lamp": Asset(ceiling_lamp, (0.5, 0.5, 0.8), ("white", "yellow"), ("glass", "metal")),
    "plant": Asset(plant, (0.5, 0.5, 1.1), ("white", "brown", "grey"), ("ceramic",), ext="obj"),
    "dining_table": Asset(table, (1.6, 0.9, 0.75), ("brown", "white", "black"), ("wood",)),
    "chair": Asset(chair, (0.45, 0.5, 0.9), ("red", "blue", "white", "black", "green"), ("wood", "plastic")),
    "counter": Asset(cabinet, (1.8, 0.6, 0.9), ("white", "grey", "beige"), ("stone", "wood")),
    "fridge": Asset(cabinet, (0.7, 0.7, 1.8), ("white", "grey", "black"), ("metal",)),
    "stove": Asset(stove, (0.6, 0.6, 0.9), ("black", "white"), ("metal",)),
    "trash_bin": Asset(bin_, (0.3, 0.3, 0.45), ("grey", "black", "blue"), ("plastic", "metal"), ext="obj"),
    "bed": Asset(bed, (1.6, 2.05, 1.0), ("blue", "grey", "beige", "white"), ("fabric", "wood")),
    "nightstand": Asset(cabinet, (0.45, 0.4, 0.55), ("white", "brown"), ("wood",)),
    "wardrobe": Asset(cabinet, (1.2, 0.6, 2.0), ("white", "brown", "grey"), ("wood",)),
    "desk": Asset(table, (1.2, 0.6, 0.75), ("white", "brown", "black"), ("wood",)),
    "office_chair": Asset(office_chair, (0.6, 0.6, 1.05), ("black", "grey", "blue"), ("fabric", "leather")),
    "toilet": Asset(toilet, (0.4, 0.65, 0.8), ("white",), ("ceramic",)),
    "sink": Asset(sink, (0.8, 0.5, 0.85), ("white", "grey"), ("ceramic",)),
    "bathtub": Asset(bathtub, (1.7, 0.75, 0.55), ("white",), ("ceramic",)),
    "washing_machine": Asset(cabinet, (0.6, 0.6, 0.85), ("white", "grey"), ("metal",)),
}

# Categories that stand above the 1.2 m band or lie flat on the floor: they may overlap other footprints.
NON_BLOCKING = frozenset({"rug", "ceiling_lamp"})
