"""The MJCF model: compiled by MjSpec, loads in MuJoCo, one mesh geom per convex part placed in world
coordinates; free and hinge joints where the USD stage has rigid bodies, masses from the densities."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
import trimesh

from sagebench.collider_export.mjcf_writer import MjcfBody, MjcfHinge, mjcf_text

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
    (tmp_path / "scene.xml").write_text(mjcf_text("tiny", bodies, meshes=meshes, floor_height=0.0))
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
    assert mjcf_text("x", bodies, meshes=MESHES) == mjcf_text("x", bodies, meshes=MESHES)
    assert 'meshdir="colliders' in mjcf_text("x", bodies, meshes=MESHES)


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
        mjcf_text("x", [MjcfBody("a_1", ["missing.stl"])], meshes=MESHES)
