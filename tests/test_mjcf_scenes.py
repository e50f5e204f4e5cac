"""scene.xml as a MuJoCo user meets it, on the demo and on a Sweet Home 3D catalogue scene: every door swings
under a push, and nothing moves when the model is just stepped (at rest where the scene places it)."""

from __future__ import annotations

import math
from pathlib import Path

import mujoco
import numpy as np
import pytest

FIXTURE = Path(__file__).parent / "fixtures" / "sh3d_cc0"
PUSH_NM = 60.0  # a firm push: about 75 N at a door's handle


@pytest.fixture(scope="module")
def catalogue_run(tmp_path_factory) -> Path:
    """The seed-0 apartment furnished from the CC0 fixtures, built and exported (fast colliders)."""
    from sagebench.scene.synth import write_synth_scene
    from sagebench.settings.export_usd import ColliderSettings, ExportConfig
    from sagebench.stages.build_scene import build_scene
    from sagebench.stages.export_usd import export_usd

    root = tmp_path_factory.mktemp("catalogue")
    write_synth_scene(root / "scene", seed=0, furniture=FIXTURE)
    build_scene(root / "scene", root / "run")
    export_usd(root / "run", config=ExportConfig(colliders=ColliderSettings(mode="fast")), cache_dir=root / "cache")
    return root / "run"


@pytest.fixture(params=["demo", "catalogue"])
def model(request) -> mujoco.MjModel:
    run = request.getfixturevalue("demo_eval_run" if request.param == "demo" else "catalogue_run")
    return mujoco.MjModel.from_xml_path(str(run / "scenes" / "demo_apartment_0" / "scene.xml"))


def world_vertices(m: mujoco.MjModel, d: mujoco.MjData, body: int) -> np.ndarray:
    """[V, 3] every mesh vertex of the body's geoms where they are now (rotation included)."""
    out = []
    for g in np.flatnonzero(m.geom_bodyid == body):
        mesh = m.geom_dataid[g]
        v = m.mesh_vert[m.mesh_vertadr[mesh]: m.mesh_vertadr[mesh] + m.mesh_vertnum[mesh]]
        out.append(d.geom_xpos[g] + v @ d.geom_xmat[g].reshape(3, 3).T)
    return np.concatenate(out)


def test_two_seconds_of_stepping_moves_no_object_a_centimetre(model):
    m = model
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    assert min((c.dist for c in d.contact[: d.ncon]), default=0.0) > -0.005  # no interpenetration over 5 mm
    jointed = sorted({int(m.jnt_bodyid[j]) for j in range(m.njnt)})
    assert len(jointed) >= 20  # free furniture and hinged doors
    start = {b: world_vertices(m, d, b) for b in jointed}
    for _ in range(round(2.0 / m.opt.timestep)):
        mujoco.mj_step(m, d)
    moved = {m.body(b).name: float(np.linalg.norm(world_vertices(m, d, b) - start[b], axis=1).max()) for b in jointed}
    assert {name: cm for name, cm in moved.items() if cm > 0.01} == {}


def test_a_push_swings_every_door_at_least_60_degrees(model):
    """A door pushed one way for 2 s, then the other way for 2 s, sweeps at least 60 degrees (the whole way to
    each stop: closed, fully open), whatever its state's angle."""
    m = model
    hinges = [j for j in range(m.njnt) if m.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE]
    assert len(hinges) == 7
    steps = round(2.0 / m.opt.timestep)
    for j in hinges:
        d = mujoco.MjData(m)
        dof, adr = m.jnt_dofadr[j], m.jnt_qposadr[j]
        ends = []
        for direction in (-1.0, 1.0):
            for _ in range(steps):
                d.qfrc_applied[dof] = direction * PUSH_NM
                mujoco.mj_step(m, d)
            ends.append(float(d.qpos[adr]))
        assert math.degrees(ends[1] - ends[0]) >= 60.0, m.joint(j).name
