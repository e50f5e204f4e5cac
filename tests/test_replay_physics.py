"""MuJoCo replay on a tiny inline room: free paths are traced exactly, walls and table corners block or push."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from sagebench.metrics.polyline import distance_to_polyline
from sagebench.replay.physics import AGENT_GEOM, agent_prism, build_replay_model, replay_batch, replay_one, time_limit
from sagebench.settings.shared import ReplayConfig


@pytest.fixture(scope="module")
def room(room_mjcf):
    return build_replay_model(mujoco.MjSpec.from_string(room_mjcf), floor_bodies=["floor_3"])


def _path(*points: tuple[float, float], yaw: float | None = None) -> np.ndarray:
    p = np.array(points, dtype=np.float64)
    seg = np.diff(p, axis=0)
    yaws = np.arctan2(seg[:, 1], seg[:, 0]) if len(p) > 1 else np.zeros(0)
    start_yaw = yaws[0] if yaw is None and len(yaws) else (yaw or 0.0)
    return np.column_stack([p, np.zeros(len(p)), np.concatenate([[start_yaw], yaws])])


def test_free_straight_path_is_traced_exactly(room):
    rec = replay_one(room, _path((0, -1), (2.5, -1)))
    assert rec.outcome == "reached"
    assert not rec.contact.any() and rec.intensity.max() == 0.0 and rec.penetration.max() == 0.0
    np.testing.assert_allclose(rec.poses[:, 1], -1.0, atol=1e-9)  # never leaves the line
    assert np.linalg.norm(rec.poses[-1, :2] - [2.5, -1]) < room.config.waypoint_tolerance
    # deadbeat drive: full speed from the first step, so 2.5 m at 0.8 m/s takes ~63 steps of 0.05 s
    assert rec.achieved[1, 0] == pytest.approx(room.config.max_speed)
    assert rec.steps == pytest.approx(2.5 / 0.8 / 0.05, abs=2)


def test_corner_turns_in_place_and_respects_limits(room):
    rec = replay_one(room, _path((0, -1), (2.0, -1), (2.0, -2.5)))
    assert rec.outcome == "reached" and not rec.contact.any()
    cfg = room.config
    assert np.abs(rec.command[:, 0]).max() <= cfg.max_speed + 1e-12
    assert np.abs(rec.command[:, 1]).max() <= cfg.max_turn_rate + 1e-12
    # turn-then-drive: the corner is turned on the spot (driving resumes within turn_in_place), not cut
    assert distance_to_polyline(rec.poses, np.array([[0, -1], [2.0, -1], [2.0, -2.5]])).max() < 0.01
    assert rec.poses[-1, 3] == pytest.approx(-math.pi / 2, abs=0.01)


def test_coincident_waypoints_are_turn_commands(room):
    path = np.array([[0, -1, 0, 0], [0, -1, 0, 1.0], [0.5, -1, 0, 0], [0.5, -1, 0, -1.5]])
    rec = replay_one(room, path)
    assert rec.outcome == "reached"
    assert rec.poses[-1, 3] == pytest.approx(-1.5, abs=1e-3)
    assert rec.poses[:, 3].max() == pytest.approx(1.0, abs=1e-3)  # it did turn to the first commanded yaw


@pytest.mark.parametrize("first", [0.059, 0.0585, 0.099])
def test_a_waypoint_within_the_tolerance_of_one_reached_short_is_still_walked_to(room, first):
    """Two passage anchors 1.5 cm apart (as build-scene's chains of narrow cells hold them, issue 38): the agent
    counts the first reached up to 2 cm short of it (0.8 m/s x 0.05 s = 4 cm a step), which left the second,
    a turn command, 3.4 cm away; it turned on the spot and stalled there. It drives to it, then turns."""
    path = _path((0, -1), (first, -1), (first + 0.015, -1), (first + 0.015, -0.2))
    rec = replay_one(room, path)
    assert rec.outcome == "reached" and not rec.contact.any()
    assert np.linalg.norm(rec.poses[-1, :2] - path[-1, :2]) < room.config.waypoint_tolerance
    assert distance_to_polyline(rec.poses, path).max() < 0.01


def test_wall_blocks_the_agent(room):
    rec = replay_one(room, _path((0, -1), (4.5, -1)))
    assert rec.outcome != "reached"
    # stopped by the wall face at x = 2.95: centre at 2.95 - radius (within the soft contact's give)
    assert rec.poses[-1, 0] == pytest.approx(2.95 - 0.2, abs=0.02)
    first = np.flatnonzero(rec.contact)[0]
    assert rec.intensity[:first].max() == 0.0
    assert rec.intensity.max() == pytest.approx(1.0, abs=0.05)  # pushing straight into it: all motion blocked
    assert rec.penetration.max() > 0


def test_table_corner_pushes_the_agent_aside(room):
    path = _path((0, -0.0), (2.5, -0.0))  # the agent's edge passes 0.1 m inside the table corner (1.1, 0.1)
    rec = replay_one(room, path)
    assert rec.contact.any()
    assert rec.poses[:, 1].min() < -0.05  # deflected away from the table (-y)
    assert rec.intensity.max() > 0.3


def _boxes_mjcf(floor_z: float, boxes: dict[str, tuple[tuple[float, float, float], tuple[float, float, float]]]) -> str:
    """A ground plane at floor_z and one body per box (lo, hi corners, z above the floor)."""
    assets, bodies = [], []
    for name, (lo, hi) in boxes.items():
        v = [(x, y, floor_z + z) for z in (lo[2], hi[2]) for y in (lo[1], hi[1]) for x in (lo[0], hi[0])]
        assets.append(f"<mesh name='{name}' vertex='{' '.join(f'{a} {b} {c}' for a, b, c in v)}'/>")
        bodies.append(f"<body name='{name}_1'><geom type='mesh' mesh='{name}'/></body>")
    return (f"<mujoco><asset>{''.join(assets)}</asset><worldbody><geom type='plane' size='0 0 1' pos='0 0 {floor_z}'/>"
            f"{''.join(bodies)}</worldbody></mujoco>")


@pytest.mark.parametrize("floor_z", [0.0, 3.0])
def test_a_30_cm_stool_stops_the_agent_and_a_3_cm_threshold_does_not(floor_z):
    """The agent's body spans the map's blocking band, 0.05..1.2 m above the floor: what the map blocks stops
    it, what lies under the band (a threshold strip) it drives over."""
    scene = _boxes_mjcf(floor_z, {"threshold": ((0.5, -1, 0), (0.6, 1, 0.03)),
                                  "stool": ((1.0, -0.2, 0), (1.4, 0.2, 0.3))})
    rm = build_replay_model(mujoco.MjSpec.from_string(scene), floor_z=floor_z)
    rec = replay_one(rm, _path((0, 0), (2.5, 0)))
    assert rec.outcome != "reached"
    assert rec.poses[-1, 0] == pytest.approx(1.0 - 0.2, abs=0.02)  # against the stool's face, past the threshold
    assert not rec.contact[rec.poses[:, 0] < 0.75].any()


def test_floor_slab_and_ground_never_touch(room):
    rec = replay_one(room, _path((-2, -2), (-2, 2)))
    assert not rec.contact.any()


def test_batch_matches_reference_loop(room):
    paths = [_path((0, -1), (2.5, -1)), _path((0, -1), (4.5, -1)), _path((0, 0), (2.5, 0.05)),
             _path((0, -1), (2.0, -1), (2.0, -2.5)), _path((1, 1), yaw=0.3)]
    for threads in (1, 2):
        for fast, ref in zip(replay_batch(room, paths, threads=threads), [replay_one(room, p) for p in paths]):
            assert fast.outcome == ref.outcome and fast.steps == ref.steps
            np.testing.assert_array_equal(fast.poses, ref.poses)
            np.testing.assert_array_equal(fast.intensity, ref.intensity)
            np.testing.assert_array_equal(fast.penetration, ref.penetration)


def test_single_pose_path_ends_at_once(room):
    rec = replay_one(room, _path((1, -1), yaw=0.3))
    assert rec.steps == 0 and rec.outcome == "reached"
    np.testing.assert_allclose(rec.poses, [[1, -1, 0, 0.3]])


def test_prism_circumscribes_the_cylinder():
    v = agent_prism(0.2, 0.05, 1.2)
    assert v.shape == (64, 3)
    r = np.linalg.norm(v[:, :2], axis=1)
    assert r.min() >= 0.2 and r.max() < 0.2 * 1.005  # contains the cylinder, at most 1 mm wider
    assert set(np.round(v[:, 2], 9)) == {0.05, 1.2}


def test_agent_is_added_without_touching_the_callers_spec(room_mjcf):
    spec = mujoco.MjSpec.from_string(room_mjcf)
    rm = build_replay_model(spec)
    assert rm.model.geom(AGENT_GEOM).id >= 0
    assert all(g.name != AGENT_GEOM for g in spec.geoms)


def test_time_limit_counts_driving_and_turning():
    cfg = ReplayConfig()
    p = _path((0, 0), (4, 0), (4, 4))
    ideal = 8 / cfg.max_speed + (math.pi / 2) / cfg.max_turn_rate
    assert time_limit(p, cfg) == pytest.approx(cfg.time_factor * ideal + cfg.time_slack)


@pytest.mark.parametrize("bad, message", [(np.zeros((3, 3)), "expected [M, 4]"), (np.zeros((0, 4)), "M >= 1"),
                                          (np.full((2, 4), np.nan), "non-finite")])
def test_bad_paths_are_rejected(room, bad, message):
    with pytest.raises(ValueError, match=message.replace("[", r"\[")):
        replay_one(room, bad)


def test_unknown_floor_body_is_an_error(room_mjcf):
    with pytest.raises(ValueError, match="no body named 'floor_9'"):
        build_replay_model(mujoco.MjSpec.from_string(room_mjcf), floor_bodies=["floor_9"])


def test_scene_joints_are_removed_so_a_free_wall_still_blocks(room_mjcf):
    """The export gives movable furniture free joints and doors hinges; replay walks the world as exported."""
    jointed = room_mjcf.replace("<body name='wall_1'>", "<body name='wall_1'><freejoint/>").replace(
        "<body name='table_2'>", "<body name='table_2'><joint type='hinge' axis='0 0 1' pos='1.1 0.1 0'/>")
    model = build_replay_model(mujoco.MjSpec.from_string(jointed), floor_bodies=["floor_3"])
    assert model.model.njnt == 3  # the agent's x, y and yaw
    rec = replay_one(model, _path((0, -1), (4.5, -1)))
    assert rec.outcome != "reached" and rec.poses[-1, 0] == pytest.approx(2.95 - 0.2, abs=0.02)
