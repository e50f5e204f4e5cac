"""Low-level template instructions (SAGE-Bench appendix C.2): Base_Action and Single_Goal.

Base_Action reads the waypoint path as a person would say it: the agent starts facing the first
segment; turns under 20 degrees are folded into walking straight, legs shorter than 0.25 m are
folded into the turns around them, and a turn with no leg after it is dropped. Each leg's turn and
distance are aimed from where the stated numbers so far lead (so rounding errors do not add up), and
the sentence uses the coarsest rounding (15 degrees and half metres, whole metres from 10 m; then
5 degrees and quarter metres; then 1 degree and 10 cm) whose literal execution (execution.py) ends
within the goal radius without crossing a blocked cell; "about" marks a number rounding moved.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sagebench.instructions.base import Instruction, TrajectoryText
from sagebench.instructions.execution import execute_sentence

MERGE_TURN_DEG = 20.0  # smaller heading changes are "keep walking"
MIN_LEG_M = 0.25  # shorter legs are not worth a sentence
_FORWARD = ("walk forward", "go straight", "move forward")
_STOP = ("then stop", "and stop there", "then stop and wait")
_SINGLE_GOAL = (
    "Walk from {s} to {g}.",
    "Go from {s} to {g}.",
    "Starting {at} {s}, walk to {g}.",
    "Make your way from {s} to {g}.",
    "Head from {s} over to {g}.",
)


@dataclass(frozen=True)
class Step:
    kind: str  # "forward" or "turn"
    amount: float  # metres forward, or degrees turned counter-clockwise (left positive)


def path_steps(waypoints: np.ndarray, merge_turn_deg: float = MERGE_TURN_DEG) -> list[Step]:  # waypoints: [M, 4]
    """The path as alternating forward legs and turns, turns under `merge_turn_deg` and short legs folded in."""
    return _fold(waypoints, merge_turn_deg, MIN_LEG_M)[0]


def leg_ends(waypoints: np.ndarray, merge_turn_deg: float = MERGE_TURN_DEG,
             min_leg_m: float = MIN_LEG_M) -> np.ndarray:  # [M, 4] -> [L, 2]
    """The waypoints where the forward legs of `path_steps` end, the path's end last; world metres."""
    ends = _fold(waypoints, merge_turn_deg, min_leg_m)[1]
    pts = np.asarray(waypoints, dtype=np.float64)[:, :2]
    return np.asarray([*ends[:-1], pts[-1]]) if ends else pts[-1:]


def _fold(waypoints: np.ndarray, merge_turn_deg: float, min_leg_m: float) -> tuple[list[Step], list[np.ndarray]]:
    pts = np.asarray(waypoints, dtype=np.float64)[:, :2]
    d = np.diff(pts, axis=0)
    lengths = np.hypot(d[:, 0], d[:, 1])
    headings = np.arctan2(d[:, 1], d[:, 0])
    steps: list[Step] = []
    ends: list[np.ndarray] = []
    heading, leg = None, 0.0
    for i, (length, yaw) in enumerate(zip(lengths, headings, strict=True)):
        if length == 0:
            continue
        turn = 0.0 if heading is None else math.degrees(_wrap(yaw - heading))
        if abs(turn) < merge_turn_deg or (heading is not None and turn == 0):
            leg += length
            heading = yaw if heading is None else heading
            continue
        _close_leg(steps, ends, leg, pts[i], min_leg_m)
        if steps and steps[-1].kind == "turn":  # no leg worth saying since the last turn: one combined turn
            turn = steps.pop().amount + turn
        if abs(turn) >= merge_turn_deg:
            steps.append(Step("turn", turn))
        heading, leg = yaw, length
    _close_leg(steps, ends, leg, pts[-1], min_leg_m)
    while steps and steps[-1].kind == "turn":  # turning on the spot at the goal is not worth saying
        steps.pop()
    return steps, ends


def _close_leg(steps: list[Step], ends: list[np.ndarray], leg: float, end: np.ndarray, min_leg_m: float) -> None:
    if leg >= min_leg_m:
        steps.append(Step("forward", leg))
        ends.append(end)


def _wrap(a: float) -> float:
    return (a + math.pi) % (2 * math.pi) - math.pi


@dataclass(frozen=True)
class Rounding:
    """How coarsely a sentence states its numbers: angles to `angle_deg`, distances to `metres` (`far_metres`
    from 10 m on); path bends under `merge_turn_deg` are walked straight through, and turns under it not said;
    legs under `min_leg_m` fold into the turns around them."""

    angle_deg: float
    metres: float
    far_metres: float
    merge_turn_deg: float
    min_leg_m: float


# tried in order, coarse (as people say it) to fine, until the literal execution reaches the goal
ROUNDINGS = (Rounding(15, 0.5, 1.0, MERGE_TURN_DEG, MIN_LEG_M), Rounding(5, 0.25, 0.5, 5, MIN_LEG_M),
             Rounding(1, 0.1, 0.1, 1e-9, 0.0))


def say_distance(metres: float, rounding: Rounding = ROUNDINGS[0]) -> str:
    """3.1 -> "3 metres", 2.7 -> "about 2.5 metres", 0.4 -> "half a metre", 12.6 -> "about 13 metres"."""
    said = _said_distance(metres, rounding)
    text = "half a metre" if said == 0.5 else "1 metre" if said == 1 else f"{said:g} metres"
    return f"about {text}" if abs(metres - said) > 0.1 else text


def _said_distance(metres: float, rounding: Rounding) -> float:
    q = rounding.metres if metres < 10 else rounding.far_metres
    return round(max(q, round(metres / q) * q), 2)


def _said_turn(degrees: float, rounding: Rounding) -> float:
    said = round(degrees / rounding.angle_deg) * rounding.angle_deg
    return 0.0 if abs(degrees) < rounding.merge_turn_deg else float(max(-180, min(180, said)))


def say_turn(degrees: float, rounding: Rounding = ROUNDINGS[0]) -> str:
    """Left for counter-clockwise: 88 -> "turn left about 90 degrees", -25 -> "turn right about 30 degrees"."""
    said = _said_turn(degrees, rounding)
    if abs(said) == 180:
        return "turn around"
    about = "about " if abs(abs(degrees) - abs(said)) > 1 else ""
    return f"turn {'left' if said > 0 else 'right'} {about}{abs(said):g} degrees"


def plan_actions(waypoints: np.ndarray, rounding: Rounding) -> list[tuple[float, float, float, float]]:
    """(turn said, turn needed, distance said, distance needed) per leg, aiming from the pose the said numbers
    reach at the next leg end, so rounding errors do not add up along the path."""
    wps = np.asarray(waypoints, dtype=np.float64)
    pos, heading = wps[0, :2].copy(), float(wps[0, 3])
    out = []
    for end in leg_ends(wps, rounding.merge_turn_deg, rounding.min_leg_m):
        vec = end - pos
        dist = float(np.hypot(*vec))
        if dist < rounding.metres / 2:
            continue
        turn = math.degrees(_wrap(math.atan2(vec[1], vec[0]) - heading))
        said_turn = _said_turn(turn, rounding)
        heading += math.radians(said_turn)
        said = _said_distance(dist, rounding)
        pos = pos + said * np.array([math.cos(heading), math.sin(heading)])
        out.append((said_turn, turn, said, dist))
    return out


def _sentence(plan: list[tuple[float, float, float, float]], rounding: Rounding, forward: str, stop: str) -> str:
    clauses = []
    for said_turn, turn, _, dist in plan:
        walk = f"{forward} {say_distance(dist, rounding)}"
        clauses.append(f"{say_turn(turn, rounding)} and {walk}" if said_turn else walk)
    return _capitalise(f"{', '.join(clauses)}, {stop}." if clauses else "Stop here.")


def base_action(text: TrajectoryText, rng: np.random.Generator) -> list[Instruction]:
    """One step-by-step instruction for the path, in the coarsest rounding whose literal execution from the
    start pose ends within the goal radius without crossing a blocked cell; wording varies with `rng`."""
    forward = _FORWARD[rng.integers(len(_FORWARD))]
    stop = _STOP[rng.integers(len(_STOP))]
    wps = np.asarray(text.waypoints, dtype=np.float64)
    for rounding in ROUNDINGS:
        sentence = _sentence(plan_actions(wps, rounding), rounding, forward, stop)
        run = execute_sentence(sentence, wps[0, :2], float(wps[0, 3]), wps[-1, :2], text.blocked)
        if run.ok(text.goal_radius):
            break
    return [Instruction("low", "Base_Action", sentence, "template")]


def single_goal(text: TrajectoryText, rng: np.random.Generator) -> list[Instruction]:
    """One "from A to B" instruction naming both endpoints; wording varies with `rng`."""
    template = _SINGLE_GOAL[rng.integers(len(_SINGLE_GOAL))]
    at = "in" if text.start_kind == "room" else "at"
    return [Instruction("low", "Single_Goal", _capitalise(template.format(s=text.start_name, g=text.goal_name, at=at)),
                        "template")]


def _capitalise(s: str) -> str:
    return s[:1].upper() + s[1:]
