"""The MJCF model: compiled by MjSpec, loads in MuJoCo, one mesh geom per convex part placed in world
coordinates; free and hinge joints where the USD stage has rigid bodies, masses from the densities."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest
import trimesh

from sagebench.collider_export.mjcf_writer import MjcfBody, MjcfHinge, mjcf_model

BOXES = {
    "wall_1/part_000.stl": ((0.1, 4.0, 2.7), (3.05, 0.0, 1.35)),
    "sofa_2/part_000.stl": ((1.0, 0.4, 0.5), (0.0, -1.5, 0.25)),
    "sofa_2/part_001.stl": ((0.4, 1.0, 0.5), (-0.3, -0.8, 0.25)),
}
MESHES = {rel: trimesh.creation.box(size).apply_translation(centre).export(file_type="stl")
          for rel, (size, centre) in BOXES.items()}


def write_model(tmp_path, bodies, meshes=MESHES):
    for rel, data in meshes.items():
        (tmp_path / "colliders" / rel).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / "colliders" / rel).write_bytes(data)
    (tmp_path / "scene.xml").write_text(mjcf_model("tiny", bodies, meshes=meshes, floor_height=0.0).xml)
    m = mujoco.MjModel.from_xml_path(str(tmp_path / "scene.xml"))
    return m, mujoco.MjData(m)


@pytest.fixture
def model(tmp_path):
    """A wall slab (x in [3, 3.1]) and an L made of two boxes, written as world-frame STL parts."""
    return write_model(tmp_path, [MjcfBody("wall_1", ["wall_1/part_000.stl"]),
                                  MjcfBody("sofa_2", ["sofa_2/part_000.stl", "sofa_2/part_001.stl"])])


def ray(m, d, origin, direction) -> tuple[float, str]:
    geom = np.zeros(1, np.int32)
    dist = mujoco.mj_ray(m, d, np.asarray(origin, float), np.asarray(direction, float), None, 1, -1, geom)
    return dist, m.geom(geom[0]).name


def test_geoms_bodies_and_ground(model):
    m, _ = model
    assert m.nmesh == 3 and m.ngeom == 4  # three parts and the ground plane
    assert [m.body(i).name for i in range(1, m.nbody)] == ["wall_1", "sofa_2"]
    assert m.geom("ground").type == mujoco.mjtGeom.mjGEOM_PLANE
    assert m.njnt == 0  # a fixed collision world


def test_ray_hits_the_wall_at_its_known_distance(model):
    m, d = model
    mujoco.mj_forward(m, d)
    dist, name = ray(m, d, (0.0, 0.5, 1.0), (1.0, 0.0, 0.0))
    assert name == "wall_1_p000" and dist == pytest.approx(3.0, abs=0.02)


def test_ray_hits_each_part_of_a_concave_object_where_it_is(model):
    m, d = model
    mujoco.mj_forward(m, d)
    assert ray(m, d, (0.3, -3.0, 0.3), (0.0, 1.0, 0.0)) == (pytest.approx(1.3, abs=0.02), "sofa_2_p000")
    # between the L's arms there is no hull: the ray passes above the short arm and hits the wall
    dist, name = ray(m, d, (0.3, -0.8, 0.3), (1.0, 0.0, 0.0))
    assert name == "wall_1_p000" and dist == pytest.approx(2.7, abs=0.02)
    dist, name = ray(m, d, (0.5, 0.5, 1.0), (0.0, 0.0, -1.0))
    assert name == "ground" and dist == pytest.approx(1.0, abs=1e-6)


def test_same_inputs_give_the_same_text():
    bodies = [MjcfBody("wall_1", ["wall_1/part_000.stl"])]
    assert mjcf_model("x", bodies, meshes=MESHES) == mjcf_model("x", bodies, meshes=MESHES)
    assert 'meshdir="colliders' in mjcf_model("x", bodies, meshes=MESHES).xml


def test_free_and_hinge_joints_with_masses_from_the_density(tmp_path):
    """The L sofa free at 70 kg/m^3 (2 x 0.2 m^3 = 0.4 m^3 -> 28 kg); the wall a door leaf on a hinge at
    x 3, y -2 held at -0.5 rad, range -1.5..0."""
    hinge = MjcfHinge(pos=(3.0, -2.0, 0.0), angle=-0.5, lower=-1.5, upper=0.0)
    m, d = write_model(tmp_path, [
        MjcfBody("door_1", ["wall_1/part_000.stl"], joint="hinge", hinge=hinge, density=400.0),
        MjcfBody("sofa_2", ["sofa_2/part_000.stl", "sofa_2/part_001.stl"], joint="free", density=70.0)])
    door, sofa = m.joint("door_1_hinge"), m.joint("sofa_2_free")
    assert door.type == mujoco.mjtJoint.mjJNT_HINGE and sofa.type == mujoco.mjtJoint.mjJNT_FREE
    assert m.qpos0[door.qposadr[0]] == pytest.approx(-0.5)  # the pose written is the state's angle
    assert list(door.range) == [-1.5, 0.0] and door.limited[0]
    assert np.allclose(door.axis, [0, 0, 1])
    mujoco.mj_forward(m, d)
    assert np.allclose(d.xanchor[door.id], [3.0, -2.0, 0.0])
    assert m.body("sofa_2").mass[0] == pytest.approx(0.4 * 70.0, rel=1e-6)
    assert m.body("door_1").mass[0] == pytest.approx(0.1 * 4.0 * 2.7 * 400.0, rel=1e-6)


def test_a_model_mujoco_refuses_is_never_written():
    with pytest.raises(ValueError, match="missing.stl"):
        mjcf_model("x", [MjcfBody("a_1", ["missing.stl"])], meshes=MESHES)


LEAF = {"door_1/part_000.stl": trimesh.creation.box((0.9, 0.04, 2.0)).apply_translation((0.45, 0.0, 1.016))
        .export(file_type="stl")}  # a leaf hinged at the origin, 1.6 cm above the floor


def door_model(tmp_path, angle: float = 0.0):
    hinge = MjcfHinge(pos=(0.0, 0.0, 0.0), angle=angle, lower=0.0, upper=math.pi / 2)
    return write_model(tmp_path, [MjcfBody("door_1", list(LEAF), joint="hinge", hinge=hinge, density=400.0)], LEAF)


@pytest.mark.parametrize("torque", [2.0, 5.0])
def test_door_servo_and_damping_are_the_usd_drive(tmp_path, torque):
    """Held at its state's angle by stiffness k: a steady torque t turns it t / k further (the USD drive's spring),
    and the hinge is damped with the drive's damping."""
    from sagebench.collider_export.bodies import DOOR_HOLD_DAMPING_NMS_PER_RAD, DOOR_HOLD_STIFFNESS_NM_PER_RAD

    m, d = door_model(tmp_path, angle=0.4)
    joint = m.joint("door_1_hinge")
    assert joint.damping[0] == DOOR_HOLD_DAMPING_NMS_PER_RAD
    assert m.actuator("door_1_hold").gainprm[0] == DOOR_HOLD_STIFFNESS_NM_PER_RAD
    for _ in range(1500):  # 15 s: settled (time constant about inertia / damping, under a second)
        d.qfrc_applied[joint.dofadr[0]] = torque
        mujoco.mj_step(m, d)
    assert d.qpos[joint.qposadr[0]] == pytest.approx(0.4 + torque / DOOR_HOLD_STIFFNESS_NM_PER_RAD, abs=1e-3)


def test_ctrl_zero_holds_the_state_angle_and_ctrl_swings_from_it(tmp_path):
    m, d = door_model(tmp_path, angle=0.4)
    q = m.joint("door_1_hinge").qposadr[0]
    for _ in range(300):
        mujoco.mj_step(m, d)
    assert d.qpos[q] == pytest.approx(0.4, abs=1e-6)  # at rest where written
    d.ctrl[0] = 0.5
    for _ in range(1500):
        mujoco.mj_step(m, d)
    assert d.qpos[q] == pytest.approx(0.9, abs=1e-3)
    assert list(m.actuator("door_1_hold").ctrlrange) == pytest.approx([-0.4, math.pi / 2 - 0.4], abs=1e-5)  # 6 digits


def test_bodies_overlapping_where_placed_do_not_collide_and_nothing_moves(tmp_path):
    """A rug (free, 1 cm) under a sofa's feet (static, standing in it): excluded, so at t = 0 nothing pops."""
    meshes = {"rug_1/part_000.stl": trimesh.creation.box((2, 2, 0.01)).apply_translation((0, 0, 0.005)),
              "sofa_2/part_000.stl": trimesh.creation.box((0.1, 0.1, 0.4)).apply_translation((0.5, 0.5, 0.2)),
              "chair_3/part_000.stl": trimesh.creation.box((0.4, 0.4, 0.4)).apply_translation((3, 0, 0.2))}
    meshes = {k: v.export(file_type="stl") for k, v in meshes.items()}
    bodies = [MjcfBody("rug_1", ["rug_1/part_000.stl"], joint="free", density=200.0),
              MjcfBody("sofa_2", ["sofa_2/part_000.stl"]),
              MjcfBody("chair_3", ["chair_3/part_000.stl"], joint="free", density=100.0)]
    model = mjcf_model("x", bodies, meshes=meshes)
    assert model.exclude == (("rug_1", "sofa_2"),)  # the chair stands clear: no exclusion
    m, d = write_model(tmp_path, bodies, meshes)
    mujoco.mj_forward(m, d)
    start = d.xpos.copy()
    for _ in range(200):
        mujoco.mj_step(m, d)
    assert np.abs(d.xpos - start).max() < 1e-3


def test_geom_groups_colours_and_lights(tmp_path):
    from sagebench.collider_export.mjcf_writer import GROUP_CEILING, GROUP_OBJECTS, GROUP_STRUCTURE

    bodies = [MjcfBody("wall_1", ["wall_1/part_000.stl"], group=GROUP_STRUCTURE, rgba=(0.9, 0.9, 0.8, 1.0)),
              MjcfBody("ceiling_2", ["sofa_2/part_000.stl"], group=GROUP_CEILING),
              MjcfBody("sofa_3", ["sofa_2/part_001.stl"], rgba=(0.2, 0.3, 0.4, 1.0))]
    (tmp_path / "scene.xml").write_text(mjcf_model("x", bodies, meshes=MESHES, lights=[(1.0, 2.0, 2.6)]).xml)
    for rel, data in MESHES.items():
        (tmp_path / "colliders" / rel).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / "colliders" / rel).write_bytes(data)
    m = mujoco.MjModel.from_xml_path(str(tmp_path / "scene.xml"))
    assert [int(m.geom(n).group[0]) for n in ("wall_1_p000", "ceiling_2_p000", "sofa_3_p000")] == \
        [GROUP_STRUCTURE, GROUP_CEILING, GROUP_OBJECTS]
    assert GROUP_CEILING > 2  # MuJoCo's viewer hides groups 3-5 until toggled
    assert np.allclose(m.geom("sofa_3_p000").rgba, (0.2, 0.3, 0.4, 1.0))
    assert m.nlight == 1 and np.allclose(m.light_pos[0], (1.0, 2.0, 2.6))
