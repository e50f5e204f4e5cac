"""A short human-readable summary of a loaded scene (what `check-scene` prints)."""

from __future__ import annotations

from collections import Counter

import numpy as np

from sagebench.scene.loader import LoadedScene


def summarise(scene: LoadedScene) -> str:
    spec = scene.spec
    lo = np.min([m.bounds[0] for m in scene.meshes.values()], axis=0)
    hi = np.max([m.bounds[1] for m in scene.meshes.values()], axis=0)
    kinds = Counter(o.kind for o in spec.objects)
    cats = Counter(o.category for o in spec.objects if o.kind == "object")
    doors = Counter(o.door.state for o in spec.objects if o.door)
    lines = [
        f"scene {spec.scene_id}: {len(spec.rooms)} rooms, {len(spec.objects)} objects, "
        f"{len(cats)} furniture categories",
        f"extent (m): x {lo[0]:.2f}..{hi[0]:.2f}, y {lo[1]:.2f}..{hi[1]:.2f}, z {lo[2]:.2f}..{hi[2]:.2f}; "
        f"floor at {spec.floor_height:.2f}",
        "kinds: " + ", ".join(f"{k} {n}" for k, n in sorted(kinds.items())),
        "doors: " + (", ".join(f"{s} {n}" for s, n in sorted(doors.items())) or "none"),
        "rooms: " + ", ".join(f"{r.id} ({r.type})" for r in spec.rooms),
    ]
    return "\n".join(lines)
