"""The MuJoCo model of a scene: every convex collider part as a static mesh geom, plus a ground plane.

Each scene object is a body named like its USD prim (`<category>_<instance_id>`) with no joint, so it
is welded to the world: the MJCF is the fixed collision world a replayed agent moves through (movable
furniture and door hinges live in the USD stage). Mesh files are relative to `meshdir`.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from collections.abc import Sequence
from dataclasses import dataclass


@dataclass(frozen=True)
class MjcfBody:
    name: str  # unique, also the prefix of its mesh and geom names
    mesh_files: Sequence[str]  # one convex part each, paths relative to meshdir, world frame


def mjcf_text(model: str, bodies: Sequence[MjcfBody], *, meshdir: str = "colliders", floor_height: float = 0.0) -> str:
    """MJCF XML text (same inputs give the same text)."""
    root = ET.Element("mujoco", model=model)
    ET.SubElement(root, "compiler", angle="radian", meshdir=meshdir, autolimits="true")
    ET.SubElement(root, "option", timestep="0.01", gravity="0 0 -9.81")
    default = ET.SubElement(root, "default")
    ET.SubElement(default, "geom", contype="1", conaffinity="1", condim="3", rgba="0.7 0.7 0.7 1")
    asset = ET.SubElement(root, "asset")
    world = ET.SubElement(root, "worldbody")
    ET.SubElement(world, "geom", name="ground", type="plane", size="0 0 1", pos=f"0 0 {_num(floor_height)}",
                  rgba="0.5 0.5 0.5 1")
    for body in bodies:
        el = ET.SubElement(world, "body", name=body.name)
        for i, file in enumerate(body.mesh_files):
            name = f"{body.name}_p{i:03d}"
            ET.SubElement(asset, "mesh", name=name, file=file)
            ET.SubElement(el, "geom", name=name, type="mesh", mesh=name)
    ET.indent(root)
    return ET.tostring(root, encoding="unicode") + "\n"


def _num(x: float) -> str:
    return repr(float(x))
