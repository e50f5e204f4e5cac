"""Which scene objects are rigid bodies in the exports, and their masses (one source for USD and MJCF).

A body's mass is an effective density times the volume of its convex collider parts. The parts are
solids that enclose upholstery, foliage and air, so the density is a bulk figure per kind of furniture
rather than a material's: the demo's armchairs (parts of 0.6 m^3) weigh about 43 kg at 70 kg/m^3, its
chairs 8 kg and doors 31 kg at 400 kg/m^3.
"""

from __future__ import annotations

MOVABLE_CATEGORIES: frozenset[str] = frozenset(
    {
        "chair", "office_chair", "armchair", "stool", "coffee_table", "side_table", "trash_bin", "plant",
        "floor_lamp", "rug", "box", "cushion", "pillow", "laptop", "toy", "basket", "vase",
    }
)  # furniture a robot may push aside; everything else is static
DENSITY_KG_M3 = 400.0  # bulk density of collider volume: solid wood furniture, door leaves
CATEGORY_DENSITY_KG_M3: dict[str, float] = {
    # upholstered and stuffed things: foam, springs and air inside the parts
    "armchair": 70.0, "sofa": 70.0, "bed": 70.0, "cushion": 70.0, "pillow": 70.0, "toy": 70.0,
    "plant": 100.0,  # a pot of soil under foliage that is mostly air
}
FRICTION = 1.0  # sliding friction of every collider: MuJoCo's default, and the USD physics material's
RESTITUTION = 0.0
MIN_VOLUME_M3 = 1e-6  # a body with (nearly) no collider volume still gets a positive mass


def is_movable(kind: str, category: str) -> bool:
    """Movable furniture: a free body in both exports. Doors are bodies too, on a hinge; the rest is static."""
    return kind == "object" and category in MOVABLE_CATEGORIES


def density_kg_m3(category: str) -> float:
    return CATEGORY_DENSITY_KG_M3.get(category, DENSITY_KG_M3)


def body_mass(category: str, volume_m3: float) -> float:
    """kg of a body whose collider parts hold `volume_m3` (world m^3)."""
    return float(max(volume_m3, MIN_VOLUME_M3) * density_kg_m3(category))
