"""The MuJoCo model of a scene, built with `mujoco.MjSpec` and compiled before it is written.

Every convex collider part is a mesh geom (world-frame STL relative to `meshdir`), plus a ground plane.
Each scene object is a body named like its USD prim (`<category>_<instance_id>`), and the joints match
the USD stage's: movable furniture has a free joint, a door a hinge about its vertical hinge axis whose
reference angle is the door's state (so qpos0 is the pose written) and whose range is closed..open, damped
and held at that angle by a position servo (`<name>_hold`) with the USD angular drive's figures; everything
else has no joint (welded to the world). A body's geoms take the density that gives its USD MassAPI mass.

For people looking at it: each body has its Gaussians' mean colour, structure (walls, floors, doors, windows)
is geom group 1, ceilings group 3 (hidden by MuJoCo's viewer until toggled: the scene shows from above), the
rest group 0; a light hangs under the ceiling over each room. Bodies that overlap where the scene places them
(a sofa's feet in a rug) do not collide with each other (`<contact><exclude>`), so the model is at rest at t = 0.
Replay (sagebench/replay) deletes the joints, servos and exclusions: its agent moves through the fixed world
as exported.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Literal

import math

import mujoco
import numpy as np

from sagebench.collider_export.bodies import DOOR_HOLD_DAMPING_NMS_PER_RAD, DOOR_HOLD_STIFFNESS_NM_PER_RAD, FRICTION
from sagebench.collider_export.usd_writer import StageObject, is_body, object_density, prim_name
from sagebench.scene.loader import LoadedScene

GEOM_RGBA = (0.7, 0.7, 0.7, 1.0)
GROUND_RGBA = (0.5, 0.5, 0.5, 1.0)
TIMESTEP = 0.01  # s
GROUP_OBJECTS, GROUP_STRUCTURE, GROUP_CEILING = 0, 1, 3  # MuJoCo's viewer shows groups 0-2 until toggled
STRUCTURE_KINDS = frozenset({"wall", "floor", "door", "window"})
OVERLAP_M = 0.001  # bodies overlapping deeper than this where the scene places them get a contact exclusion


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
    rgba: tuple[float, float, float, float] = GEOM_RGBA
    group: int = GROUP_OBJECTS


def scene_body(obj: StageObject, mesh_files: Sequence[str],
               rgb: tuple[float, float, float] | None = None) -> MjcfBody:
    """The body of a stage object: its joint and density as the USD stage has them, coloured `rgb` (0..1)."""
    name = prim_name(obj)
    look = {"rgba": GEOM_RGBA if rgb is None else (*(float(c) for c in rgb), 1.0),
            "group": GROUP_CEILING if obj.kind == "ceiling" else
            GROUP_STRUCTURE if obj.kind in STRUCTURE_KINDS else GROUP_OBJECTS}
    if not is_body(obj):
        return MjcfBody(name, mesh_files, **look)
    density = object_density(obj)
    if obj.door is None:
        return MjcfBody(name, mesh_files, joint="free", density=density, **look)
    door = obj.door
    full = math.radians(door.open_deg) * door.swing
    hinge = MjcfHinge(pos=tuple(float(v) for v in door.hinge), angle=door.angle_rad(),
                      lower=min(0.0, full), upper=max(0.0, full))
    return MjcfBody(name, mesh_files, joint="hinge", hinge=hinge, density=density, **look)


def room_lights(scene: LoadedScene, below_ceiling: float = 0.1) -> list[tuple[float, float, float]]:
    """A light point per room: above a point inside its floor polygon, `below_ceiling` m under the lowest ceiling
    (else the tallest wall's top; else 2.5 m above the floor)."""
    from shapely.geometry import Polygon

    spec = scene.spec
    ceilings = [scene.meshes[o.instance_id].bounds[0, 2] for o in spec.objects if o.kind == "ceiling"]
    walls = [scene.meshes[o.instance_id].bounds[1, 2] for o in spec.objects if o.kind == "wall"]
    top = min(ceilings) if ceilings else max(walls) if walls else spec.floor_height + 2.5
    out = []
    for room in spec.rooms:
        p = Polygon(room.polygon).representative_point()
        out.append((round(float(p.x), 6), round(float(p.y), 6), round(float(top) - below_ceiling, 6)))
    return out


def build_spec(model: str, bodies: Sequence[MjcfBody], *, meshdir: str = "colliders",
               floor_height: float = 0.0, lights: Sequence[tuple[float, float, float]] = (),
               exclude: Sequence[tuple[str, str]] = ()) -> mujoco.MjSpec:
    """The scene as an MjSpec (not yet compiled; its mesh files are named, not loaded); `lights` are world
    points, `exclude` pairs of body names that do not collide."""
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
                            pos=[0.0, 0.0, float(floor_height)], rgba=list(GROUND_RGBA), group=GROUP_STRUCTURE)
    for i, pos in enumerate(lights):
        spec.worldbody.add_light(name=f"light_{i}", pos=list(pos), dir=[0.0, 0.0, -1.0], diffuse=[0.5, 0.5, 0.5],
                                 castshadow=False)
    for body in bodies:
        el = spec.worldbody.add_body(name=body.name)
        if body.joint == "free":
            el.add_freejoint(name=f"{body.name}_free")
        elif body.joint == "hinge":
            _add_hinge(spec, el, body)
        for i, file in enumerate(body.mesh_files):
            name = f"{body.name}_p{i:03d}"
            spec.add_mesh(name=name, file=file)
            g = el.add_geom(name=name, type=mujoco.mjtGeom.mjGEOM_MESH, meshname=name, rgba=list(body.rgba),
                            group=body.group)
            if body.density is not None:
                g.density = body.density
    for a, b in exclude:
        spec.add_exclude(bodyname1=a, bodyname2=b)
    return spec


def _add_hinge(spec: mujoco.MjSpec, el, body: MjcfBody) -> None:
    """The door's hinge, damped, and its servo: torque = stiffness x (angle + ctrl - q), so ctrl 0 holds the
    state's angle (as the USD drive's target) and ctrl is the swing asked of it from there."""
    if body.hinge is None:
        raise ValueError(f"{body.name}: a hinge joint needs its MjcfHinge")
    h = body.hinge
    el.add_joint(name=f"{body.name}_hinge", type=mujoco.mjtJoint.mjJNT_HINGE, axis=[0.0, 0.0, 1.0],
                 pos=list(h.pos), ref=h.angle, range=[h.lower, h.upper], damping=DOOR_HOLD_DAMPING_NMS_PER_RAD)
    k = DOOR_HOLD_STIFFNESS_NM_PER_RAD
    servo = spec.add_actuator(name=f"{body.name}_hold", target=f"{body.name}_hinge",
                              trntype=mujoco.mjtTrn.mjTRN_JOINT)
    servo.gaintype, servo.biastype = mujoco.mjtGain.mjGAIN_FIXED, mujoco.mjtBias.mjBIAS_AFFINE
    servo.gainprm[0] = k
    servo.biasprm[:3] = [k * h.angle, -k, 0.0]
    servo.ctrlrange = [h.lower - h.angle, h.upper - h.angle]


@dataclass(frozen=True)
class MjcfModel:
    xml: str  # the MJCF text
    exclude: tuple[tuple[str, str], ...]  # body pairs kept from colliding: they overlap where the scene places them


def mjcf_model(model: str, bodies: Sequence[MjcfBody], *, meshes: Mapping[str, bytes], meshdir: str = "colliders",
               floor_height: float = 0.0, lights: Sequence[tuple[float, float, float]] = ()) -> MjcfModel:
    """The scene's MJCF, compiled first against `meshes` (file name relative to meshdir -> STL bytes), so a
    model MuJoCo refuses is never written; bodies overlapping deeper than OVERLAP_M as placed (one of them
    jointed) excluded from colliding. Same inputs give the same text."""
    assets = {f"{meshdir}/{name}": data for name, data in meshes.items()}
    spec = build_spec(model, bodies, meshdir=meshdir, floor_height=floor_height, lights=lights)
    spec.assets = assets
    exclude = overlapping_bodies(spec.compile())
    spec = build_spec(model, bodies, meshdir=meshdir, floor_height=floor_height, lights=lights, exclude=exclude)
    spec.assets = assets
    spec.compile()
    return MjcfModel(spec.to_xml(), tuple(exclude))


def overlapping_bodies(m: mujoco.MjModel) -> list[tuple[str, str]]:
    """Sorted pairs of body names whose geoms penetrate deeper than OVERLAP_M at qpos0, one of them jointed."""
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    pairs = set()
    for c in d.contact[: d.ncon]:
        b1, b2 = int(m.geom_bodyid[c.geom1]), int(m.geom_bodyid[c.geom2])
        if c.dist < -OVERLAP_M and 0 not in (b1, b2) and (m.body_jntnum[b1] or m.body_jntnum[b2]):
            pairs.add(tuple(sorted((m.body(b1).name, m.body(b2).name))))
    return sorted(pairs)
