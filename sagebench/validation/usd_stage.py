"""Whether a scene's USD stage is whole: scene.usda opens, and holds a prim for every object of scene.json whose
collider parts get their points from geometry.usdc (a missing or damaged crate layer leaves them empty).

validate and verify call it: a stage that only exists, or that a byte flip broke, is not a passing one.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from pathlib import Path

from sagebench.errors import DataError
from sagebench.run_layout import USD, USD_GEOMETRY

OBJECTS = "/World/Objects"


def check_stage(scene_dir: Path, objects: Mapping[int, str]) -> None:
    """A DataError naming the file when scene_dir's stage does not open or lacks an object of `objects`
    (instance id -> category) or its collider geometry."""
    from pxr import Tf, Usd, UsdGeom

    path = Path(scene_dir) / USD
    try:
        stage = Usd.Stage.Open(str(path))
    except Tf.ErrorException as err:
        why = re.findall(r"'([^']*)'", str(err))
        raise DataError(f"cannot open as USD: {why[-1] if why else 'not a USD layer'}", path=path) from None
    if stage is None:
        raise DataError("cannot open as USD", path=path)
    errors = [str(e) for e in stage.GetCompositionErrors()] if hasattr(stage, "GetCompositionErrors") else []
    if errors:
        raise DataError(f"{errors[0]} (is {USD_GEOMETRY} missing or damaged?)", path=path)
    root = stage.GetPrimAtPath(OBJECTS)
    found = {}
    for prim in (root.GetChildren() if root else []):
        attr = prim.GetAttribute("sagebench:instanceId")
        if attr and attr.Get() is not None:
            found[int(attr.Get())] = prim
    for instance_id, category in sorted(objects.items()):
        prim = found.get(instance_id)
        if prim is None:
            raise DataError(f"no prim for object {instance_id} ({category}) under {OBJECTS}; run export-usd again",
                            path=path)
        colliders = prim.GetChild("Colliders")
        parts = colliders.GetChildren() if colliders else []
        if not parts:
            raise DataError(f"{prim.GetPath()} has no collider parts; run export-usd again", path=path)
        for part in parts:
            points = UsdGeom.Mesh(part).GetPointsAttr().Get()
            if points is None or len(points) == 0:
                raise DataError(f"{part.GetPath()} has no points: {USD_GEOMETRY} is missing or damaged; run "
                                "export-usd again", path=Path(scene_dir) / USD_GEOMETRY)
