"""Low-level templates: Base_Action says the path's legs and turns the way a person would; Single_Goal names both ends."""

import math

import numpy as np
import pytest

from sagebench.instructions.registry import GENERATORS, instructions_for
from sagebench.instructions.base import TrajectoryText
from hypothesis import given, settings
from hypothesis import strategies as st

from profiles import examples

from sagebench.instructions.execution import BlockedMap, execute_sentence, parse_actions
from sagebench.instructions.low_level import ROUNDINGS, Step, base_action, path_steps, say_distance, say_turn


def _wps(*xy):
    pts = np.array(xy, dtype=np.float64)
    return np.column_stack([pts, np.zeros(len(pts)), np.zeros(len(pts))])


@pytest.mark.parametrize("metres,text", [(3.02, "3 metres"), (2.7, "about 2.5 metres"), (0.3, "about half a metre"),
                                         (1.05, "1 metre"), (12.6, "about 13 metres"), (0.5, "half a metre")])
def test_distances_are_rounded_as_people_say_them(metres, text):
    assert say_distance(metres) == text


@pytest.mark.parametrize("deg,text", [(88, "turn left about 90 degrees"), (-47, "turn right about 45 degrees"),
                                      (-25, "turn right about 30 degrees"), (175, "turn around"),
                                      (100, "turn left about 105 degrees"), (-44, "turn right 45 degrees"),
                                      (37, "turn left about 30 degrees"), (46, "turn left 45 degrees")])
def test_turns_are_rounded_to_15_degrees_left_counter_clockwise(deg, text):
    assert say_turn(deg) == text


@pytest.mark.parametrize("text,actions", [
    ("Walk forward about 3 metres, turn left about 90 degrees and go straight half a metre, then stop.",
     [("forward", 3.0), ("turn", 90.0), ("forward", 0.5)]),
    ("Turn around and move forward 1 metre, turn right 37 degrees and walk forward 1.7 metres, and stop there.",
     [("turn", 180.0), ("forward", 1.0), ("turn", -37.0), ("forward", 1.7)])])
def test_sentences_read_back_as_the_turns_and_distances_they_state(text, actions):
    assert parse_actions(text) == actions


def _execution(wps, radius=1.0, blocked=None):
    text = TrajectoryText(wps, "the sofa", "the bed", "object", "object", goal_radius=radius, blocked=blocked)
    sentence = base_action(text, np.random.default_rng(0))[0].text
    return sentence, execute_sentence(sentence, wps[0, :2], float(wps[0, 3]), wps[-1, :2], blocked)


def _heading_wps(*xy):
    wps = _wps(*xy)
    seg = np.diff(wps[:, :2], axis=0)
    wps[:-1, 3] = np.arctan2(seg[:, 1], seg[:, 0])
    return wps


def test_a_long_leg_after_an_odd_turn_falls_back_to_finer_numbers_to_stay_within_the_radius():
    # 27 deg said as 30 over 8 m misses by 8 * 2 sin(1.5 deg) = 0.42 m: inside 1 m, outside 0.2 m
    wps = _heading_wps((0, 0), (4, 0), (4 + 8 * math.cos(math.radians(27)), 8 * math.sin(math.radians(27))))
    coarse, run = _execution(wps, radius=1.0)
    assert "turn left about 30 degrees" in coarse and run.end_error == pytest.approx(0.42, abs=0.01)
    fine, run = _execution(wps, radius=0.2)
    assert "turn left 27 degrees" in fine and run.end_error <= 0.2


def test_a_bend_walked_straight_through_that_would_cross_a_blocked_cell_is_said_leg_by_leg():
    # a 14 deg bend is walked straight through: "walk 6 metres" along y = 0 ends 0.5 m from the goal, but the
    # cell at x 3.00-3.05, y 0.00-0.05 lies on that line and not on the path (y = 0.25 there)
    wps = _heading_wps((0, 0), (2, 0), (4, 0.5), (6, 0.5))
    grid = np.zeros((40, 160), dtype=bool)  # 0.05 m cells, origin (-1, -1)
    grid[20, 80] = True
    blocked = BlockedMap(grid, 0.05, (-1.0, -1.0))
    coarse, run = _execution(wps)
    assert coarse.count("metres") == 1 and "turn" not in coarse and run.end_error == pytest.approx(0.5)
    assert execute_sentence(coarse, wps[0, :2], 0.0, wps[-1, :2], blocked).crosses_blocked
    sentence, run = _execution(wps, blocked=blocked)
    assert run.ok(1.0) and sentence.count("turn") >= 2


_LEGS = st.lists(st.tuples(st.floats(-170, 170), st.floats(0.3, 9.0)), min_size=1, max_size=6)


@settings(max_examples=examples(60))
@given(_LEGS)
def test_every_sentence_executed_literally_ends_within_the_goal_radius(legs):
    pts, heading = [np.zeros(2)], 0.0
    for turn, length in legs:
        heading += math.radians(turn)
        pts.append(pts[-1] + length * np.array([math.cos(heading), math.sin(heading)]))
    wps = _heading_wps(*pts)
    sentence, run = _execution(wps)
    assert run.end_error <= 1.0, sentence


def test_l_shaped_path_is_walk_turn_walk():
    steps = path_steps(_wps((0, 0), (3, 0), (3, 2)))
    assert [s.kind for s in steps] == ["forward", "turn", "forward"]
    assert steps[0].amount == pytest.approx(3) and steps[1].amount == pytest.approx(90) and steps[2].amount == pytest.approx(2)


def test_small_wiggles_merge_and_a_final_turn_is_dropped():
    wps = _wps((0, 0), (2, 0), (4, 0.3), (6, 0.3), (6.05, 0.35))  # 8.5 deg wiggle, then a 7 cm leg
    steps = path_steps(wps)
    assert steps == [Step("forward", pytest.approx(4 + math.hypot(2, 0.3)))]


def test_short_leg_between_two_turns_becomes_one_turn():
    steps = path_steps(_wps((0, 0), (2, 0), (2.1, 0.1), (2.1, 3)))  # 45 deg, 14 cm, 45 deg
    assert [s.kind for s in steps] == ["forward", "turn", "forward"]
    assert steps[1].amount == pytest.approx(90)


def _text(wps):
    return TrajectoryText(wps, "the dining table", "the bedroom", "object", "room")


def test_template_mode_writes_one_base_action_and_one_single_goal():
    out = instructions_for(_text(_wps((0, 0), (3, 0), (3, -2))), "template", np.random.default_rng(0))
    assert [(i.level, i.type, i.source) for i in out] == [("low", "Base_Action", "template"), ("low", "Single_Goal", "template")]
    base, goal = out[0].text, out[1].text
    assert "3 metres" in base and "turn right 90 degrees" in base and "2 metres" in base and base.endswith(".")
    assert base[0].isupper()
    assert "the dining table" in goal and "the bedroom" in goal


def test_wording_is_a_function_of_the_seed():
    t = _text(_wps((0, 0), (3, 0), (3, -2)))
    texts = {tuple(i.text for i in instructions_for(t, "template", np.random.default_rng(s))) for s in range(20)}
    assert len(texts) > 3
    assert instructions_for(t, "template", np.random.default_rng(5)) == instructions_for(t, "template", np.random.default_rng(5))


def test_none_mode_writes_nothing_and_modes_are_registered():
    assert instructions_for(_text(_wps((0, 0), (3, 0))), "none", np.random.default_rng(0)) == []
    assert set(GENERATORS) == {"template", "llm", "none"}
