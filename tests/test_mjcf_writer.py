"""The MJCF model: loads in MuJoCo, one mesh geom per convex part placed in world coordinates."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
import trimesh

from sagebench.collider_export.mjcf_writer import MjcfBody, mjcf_text


@pytest.fixture
def model(tmp_path):
    """A wall slab (x in [3, 3.1]) and an L made of two boxes, written as world-frame STL parts."""
    boxes = {
        "wall_1/part_000.stl": ((0.1, 4.0, 2.7), (3.05, 0.0, 1.35)),
        "sofa_2/part_000.stl": ((1.0, 0.4, 0.5), (0.0, -1.5, 0.25)),
        "sofa_2/part_001.stl": ((0.4, 1.0, 0.5), (-0.3, -0.8, 0.25)),
    }
    for rel, (size, centre) in boxes.items():
        (tmp_path / "colliders" / rel).parent.mkdir(parents=True, exist_ok=True)
        trimesh.creation.box(size).apply_translation(centre).export(tmp_path / "colliders" / rel)
    bodies = [MjcfBody("wall_1", ["wall_1/part_000.stl"]),
              MjcfBody("sofa_2", ["sofa_2/part_000.stl", "sofa_2/part_001.stl"])]
    (tmp_path / "scene.xml").write_text(mjcf_text("tiny", bodies, floor_height=0.0))
    m = mujoco.MjModel.from_xml_path(str(tmp_path / "scene.xml"))
    return m, mujoco.MjData(m)


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
    bodies = [MjcfBody("a_1", ["a_1/part_000.stl"])]
    assert mjcf_text("x", bodies) == mjcf_text("x", bodies)
    assert 'meshdir="colliders"' in mjcf_text("x", bodies)
