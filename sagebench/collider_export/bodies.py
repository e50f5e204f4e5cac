"""Which scene objects are rigid bodies in the exports, and their masses (one source for USD and MJCF).

A body's mass is an effective density times the volume of its convex collider parts. The parts are
solids that enclose upholstery, foliage and air, so the density is a bulk figure per kind of furniture
rather than a material's: the demo's armchairs (parts of 0.6 m^3) weigh about 43 kg at 70 kg/m^3, its
chairs 8 kg and doors 31 kg at 400 kg/m^3. Where that figure leaves the range such things weigh (a hull
closes the hollow of a bin, a lamp's shade: the demo's bins came to 12-14 kg, its floor lamps 17-18 kg), the
category's typical mass is used instead (MASS_RANGE_KG).
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
# (lightest, typical, heaviest) kg of movable furniture and door leaves: rounded figures for such household
# things (sagebench's estimates, not measurements); a density x volume mass outside the range becomes the typical one
MASS_RANGE_KG: dict[str, tuple[float, float, float]] = {
    "chair": (2.0, 6.0, 15.0), "office_chair": (8.0, 14.0, 25.0), "armchair": (12.0, 30.0, 60.0),
    "stool": (1.5, 4.0, 10.0), "coffee_table": (5.0, 15.0, 40.0), "side_table": (2.0, 6.0, 20.0),
    "trash_bin": (0.5, 2.0, 6.0), "plant": (1.0, 6.0, 25.0), "floor_lamp": (2.0, 5.0, 12.0),
    "rug": (0.5, 4.0, 20.0), "box": (0.2, 2.0, 15.0), "cushion": (0.1, 0.5, 2.0), "pillow": (0.1, 0.5, 2.0),
    "laptop": (0.8, 2.0, 4.0), "toy": (0.05, 0.3, 3.0), "basket": (0.2, 1.0, 5.0), "vase": (0.2, 1.5, 8.0),
    "door": (8.0, 25.0, 60.0),
}
# a door is held at its state's angle by a soft servo, as a door closer holds a door: USD's angular drive and
# MJCF's position actuator + hinge damping carry the same figures (a 60 N m push swings a leaf through 90 degrees)
DOOR_HOLD_STIFFNESS_NM_PER_RAD = 20.0
DOOR_HOLD_DAMPING_NMS_PER_RAD = 10.0
DOOR_FLOOR_GAP_M = 0.015  # a door leaf's colliders end this far above the floor (and clear a rug), as real doors do
FRICTION = 1.0  # sliding friction of every collider: MuJoCo's default, and the USD physics material's
RESTITUTION = 0.0
MIN_VOLUME_M3 = 1e-6  # a body with (nearly) no collider volume still gets a positive mass


def is_movable(kind: str, category: str) -> bool:
    """Movable furniture: a free body in both exports. Doors are bodies too, on a hinge; the rest is static."""
    return kind == "object" and category in MOVABLE_CATEGORIES


def density_kg_m3(category: str) -> float:
    return CATEGORY_DENSITY_KG_M3.get(category, DENSITY_KG_M3)


def body_mass(category: str, volume_m3: float) -> float:
    """kg of a body whose collider parts hold `volume_m3` (world m^3): the bulk density's mass, or the category's
    typical mass where that is outside the category's range."""
    bulk = float(max(volume_m3, MIN_VOLUME_M3) * density_kg_m3(category))
    low, typical, high = MASS_RANGE_KG.get(category, (0.0, bulk, float("inf")))
    return bulk if low <= bulk <= high else typical
