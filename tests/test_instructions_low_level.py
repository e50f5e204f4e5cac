"""Low-level templates: Base_Action says the path's legs and turns the way a person would; Single_Goal names both ends."""

import math

import numpy as np
import pytest

from sagebench.instructions import GENERATORS, instructions_for
from sagebench.instructions.base import TrajectoryText
from sagebench.instructions.low_level import Step, path_steps, say_distance, say_turn


def _wps(*xy):
    pts = np.array(xy, dtype=np.float64)
    return np.column_stack([pts, np.zeros(len(pts)), np.zeros(len(pts))])


@pytest.mark.parametrize("metres,text", [(3.02, "3 metres"), (2.7, "about 2.5 metres"), (0.3, "about half a metre"),
                                         (1.05, "1 metre"), (12.6, "about 13 metres"), (0.5, "half a metre")])
def test_distances_are_rounded_as_people_say_them(metres, text):
    assert say_distance(metres) == text


@pytest.mark.parametrize("deg,text", [(88, "turn left about 90 degrees"), (-47, "turn right about 45 degrees"),
                                      (-25, "turn slightly right"), (170, "turn around"), (100, "turn left about 105 degrees")])
def test_turns_are_rounded_to_15_degrees_left_counter_clockwise(deg, text):
    assert say_turn(deg) == text


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
    assert "3 metres" in base and "turn right about 90 degrees" in base and "2 metres" in base and base.endswith(".")
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
