"""The MuJoCo model of a scene, built with `mujoco.MjSpec` and compiled before it is written.

Every convex collider part is a mesh geom (world-frame STL relative to `meshdir`), plus a ground plane.
Each scene object is a body named like its USD prim (`<category>_<instance_id>`), and the joints match
the USD stage's: movable furniture has a free joint, a door a hinge about its vertical hinge axis whose
reference angle is the door's state (so qpos0 is the pose written) and whose range is closed..open;
everything else has no joint (welded to the world). A body's geoms take its category's bulk density,
so MuJoCo's mass equals the USD MassAPI mass. Replay (sagebench/replay) deletes the joints: its agent
moves through the fixed world as exported.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Literal

import math

import mujoco

from sagebench.collider_export.bodies import FRICTION, density_kg_m3
from sagebench.collider_export.usd_writer import StageObject, is_body, prim_name

GEOM_RGBA = (0.7, 0.7, 0.7, 1.0)
GROUND_RGBA = (0.5, 0.5, 0.5, 1.0)
TIMESTEP = 0.01  # s


@dataclass(frozen=True)
class MjcfHinge:
    """A vertical hinge in the world frame (metres, radians)."""

    pos: tuple[float, float, float]  # a point on the axis
    angle: float  # the state's angle from closed: the joint's reference (qpos0)
    lower: float  # range, closed = 0
    upper: float


@dataclass(frozen=True)
class MjcfBody:
    name: str  # unique, also the prefix of its mesh and geom names
    mesh_files: Sequence[str]  # one convex part each, paths relative to meshdir, world frame
    joint: Literal["fixed", "free", "hinge"] = "fixed"
    hinge: MjcfHinge | None = None  # with joint "hinge"
    density: float | None = None  # kg/m^3 of its geoms; None: MuJoCo's default (static bodies)


def scene_body(obj: StageObject, mesh_files: Sequence[str]) -> MjcfBody:
    """The body of a stage object: its joint and density as the USD stage has them."""
    name = prim_name(obj)
    if not is_body(obj):
        return MjcfBody(name, mesh_files)
    density = density_kg_m3(obj.category)
    if obj.door is None:
        return MjcfBody(name, mesh_files, joint="free", density=density)
    door = obj.door
    full = math.radians(door.open_deg) * door.swing
    hinge = MjcfHinge(pos=tuple(float(v) for v in door.hinge), angle=door.angle_rad(),
                      lower=min(0.0, full), upper=max(0.0, full))
    return MjcfBody(name, mesh_files, joint="hinge", hinge=hinge, density=density)


def build_spec(model: str, bodies: Sequence[MjcfBody], *, meshdir: str = "colliders",
               floor_height: float = 0.0) -> mujoco.MjSpec:
    """The scene as an MjSpec (not yet compiled; its mesh files are named, not loaded)."""
    spec = mujoco.MjSpec()
    spec.modelname = model
    spec.meshdir = meshdir
    spec.compiler.degree = False
    spec.compiler.autolimits = True
    spec.option.timestep = TIMESTEP
    spec.option.gravity = [0.0, 0.0, -9.81]
    geom = spec.default.geom
    geom.contype, geom.conaffinity, geom.condim, geom.rgba = 1, 1, 3, list(GEOM_RGBA)
    geom.friction = [FRICTION, 0.005, 0.0001]  # sliding as the USD physics material; torsion, rolling: MuJoCo's
    spec.worldbody.add_geom(name="ground", type=mujoco.mjtGeom.mjGEOM_PLANE, size=[0.0, 0.0, 1.0],
                            pos=[0.0, 0.0, float(floor_height)], rgba=list(GROUND_RGBA))
    for body in bodies:
        el = spec.worldbody.add_body(name=body.name)
        if body.joint == "free":
            el.add_freejoint(name=f"{body.name}_free")
        elif body.joint == "hinge":
            if body.hinge is None:
                raise ValueError(f"{body.name}: a hinge joint needs its MjcfHinge")
            h = body.hinge
            el.add_joint(name=f"{body.name}_hinge", type=mujoco.mjtJoint.mjJNT_HINGE, axis=[0.0, 0.0, 1.0],
                         pos=list(h.pos), ref=h.angle, range=[h.lower, h.upper])
        for i, file in enumerate(body.mesh_files):
            name = f"{body.name}_p{i:03d}"
            spec.add_mesh(name=name, file=file)
            g = el.add_geom(name=name, type=mujoco.mjtGeom.mjGEOM_MESH, meshname=name)
            if body.density is not None:
                g.density = body.density
    return spec


def mjcf_text(model: str, bodies: Sequence[MjcfBody], *, meshes: Mapping[str, bytes], meshdir: str = "colliders",
              floor_height: float = 0.0) -> str:
    """MJCF XML of the scene, compiled first against `meshes` (file name relative to meshdir -> STL bytes),
    so a model MuJoCo refuses is never written. Same inputs give the same text."""
    spec = build_spec(model, bodies, meshdir=meshdir, floor_height=floor_height)
    spec.assets = {f"{meshdir}/{name}": data for name, data in meshes.items()}
    spec.compile()
    return spec.to_xml()
