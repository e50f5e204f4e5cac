"""Verdicts on replays in the inline test room: injected bad paths fail with the right reason, clean ones pass."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from sagebench.replay.physics import ReplayRecord, build_replay_model, replay_batch
from sagebench.settings.validate import CheckConfig
from sagebench.validation.checks import judge


@pytest.fixture(scope="module")
def room(room_mjcf):
    return build_replay_model(mujoco.MjSpec.from_string(room_mjcf), floor_bodies=["floor_3"])


def _path(*points):
    p = np.array(points, dtype=np.float64)
    seg = np.diff(p, axis=0)
    yaw = np.arctan2(seg[:, 1], seg[:, 0])
    return np.column_stack([p, np.zeros(len(p)), np.concatenate([yaw[:1], yaw])])


def _verdicts(room, cases, config=CheckConfig()):
    """cases: name -> (path, goal xy, goal radius) -> name -> Verdict."""
    records = replay_batch(room, [c[0] for c in cases.values()])
    return {name: judge(rec, path, np.array(goal), goal_radius=radius, geodesic_distance=1.0,
                        timestep=room.timestep, config=config)
            for (name, (path, goal, radius)), rec in zip(cases.items(), records)}


def test_injected_bad_paths_fail_with_the_right_reason_and_clean_ones_pass(room):
    cases = {
        "straight": (_path((0, -1), (2.5, -1)), (2.5, -1), 0.5),
        "around the table": (_path((0, -0.5), (2.3, -0.5), (2.3, 1.5), (0.5, 1.5)), (0.5, 1.5), 0.5),
        "through the wall": (_path((0, -1), (4.5, -1)), (4.5, -1), 0.5),
        "clips the table corner": (_path((0, -0.02), (2.5, -0.02)), (2.5, -0.02), 0.5),
        "ends short of the goal": (_path((0, -2), (2.0, -2)), (2.0, -0.5), 1.0),
    }
    v = _verdicts(room, cases)
    for name in ("straight", "around the table"):
        assert v[name].passed, (name, v[name])
        assert v[name].csr == 1.0 and v[name].icp == 0.0 and v[name].contact_steps == 0
        assert v[name].reached_goal and v[name].collision_free
        assert 0.9 < v[name].ps <= 1.0
    assert "collision" in v["through the wall"].reasons
    assert "goal_not_reached" in v["through the wall"].reasons
    assert v["through the wall"].icp > 0.1
    assert v["clips the table corner"].reasons == ("collision",)  # pushed aside, still gets to the goal
    assert v["clips the table corner"].max_deviation > CheckConfig().deviation_tolerance
    assert v["ends short of the goal"].reasons == ("goal_not_reached",)
    assert v["ends short of the goal"].final_distance == pytest.approx(1.5, abs=0.03)


def test_a_brush_within_map_precision_passes(room):
    # the agent's edge overlaps the wall by 2 cm (less than half a 0.05 m map cell) along 1 m
    path = _path((2.0, -2.5), (2.77, -2.5), (2.77, -1.5))
    v = _verdicts(room, {"brush": (path, (2.77, -1.5), 0.5)})["brush"]
    assert v.contact_steps > 0 and v.passed, v
    strict = _verdicts(room, {"brush": (path, (2.77, -1.5), 0.5)},
                       CheckConfig(deviation_tolerance=0.0, penetration_tolerance=0.0))["brush"]
    assert strict.reasons == ("collision",)


def test_leaving_the_corridor_is_reported(room):
    # a commanded detour of 1.5 m off a straight reference: CSR < 1
    path = _path((-2, -2), (-2, 0))
    v = _verdicts(room, {"detour": (path, (-2, 0), 0.5)})["detour"]
    rec = replay_batch(room, [_path((-2, -2), (-0.5, -1), (-2, 0))])[0]
    off = judge(rec, path, np.array([-2, 0]), goal_radius=0.5, geodesic_distance=2.0, timestep=room.timestep)
    assert v.passed
    assert off.reasons == ("left_corridor",) and off.csr < 1.0


def _record(offset: float, depth: float) -> ReplayRecord:
    """A replay along y = offset of the reference (0,0)->(2,0) that reached its end after touching a collider
    once, `depth` deep (no physics: the numbers are exact)."""
    x = np.linspace(0.0, 2.0, 21)
    poses = np.column_stack([x, np.full_like(x, offset), np.zeros_like(x), np.zeros_like(x)])
    poses[-1, 1] = 0.0  # back on the reference at the end
    contact = np.zeros(len(x), bool)
    contact[10] = True
    zeros = np.zeros((len(x), 2))
    return ReplayRecord(poses=poses, command=zeros, achieved=zeros, contact=contact,
                        penetration=np.where(contact, depth, 0.0), intensity=np.zeros(len(x)), outcome="reached",
                        waypoint=1)


@pytest.mark.parametrize(("offset", "depth", "reasons"), [
    (0.0, 0.01, ()),  # exactly the 0.01 m penetration tolerance passes
    (0.0, 0.011, ("collision",)),  # 1 mm deeper fails
    (0.10, 0.0, ()),  # pushed exactly the 0.10 m deviation tolerance off the path passes
    (0.11, 0.0, ("collision",)),  # 1 cm farther fails
])
def test_default_tolerances_at_and_beyond_their_thresholds(offset, depth, reasons):
    ref = _path((0, 0), (2, 0))
    v = judge(_record(offset, depth), ref, np.array([2.0, 0.0]), goal_radius=0.5, geodesic_distance=2.0,
              timestep=0.01)
    assert (v.max_penetration, v.max_deviation) == (depth, offset)
    assert v.reasons == reasons
