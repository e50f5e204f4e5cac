"""Low-level template instructions (SAGE-Bench appendix C.2): Base_Action and Single_Goal.

Base_Action reads the waypoint path as a person would say it: the agent starts facing the first
segment; turns under 20 degrees are folded into walking straight, legs shorter than 0.25 m are
folded into the turns around them, and a turn with no leg after it is dropped; angles are rounded to 15 degrees and distances to half a metre
(whole metres from 10 m), with "about" when rounding moved the number.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sagebench.instructions.base import Instruction, TrajectoryText

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


def path_steps(waypoints: np.ndarray) -> list[Step]:  # waypoints: [M, 4] (x, y, z, yaw)
    """The path as alternating forward legs and turns, small turns and short legs folded in."""
    pts = np.asarray(waypoints, dtype=np.float64)[:, :2]
    d = np.diff(pts, axis=0)
    lengths = np.hypot(d[:, 0], d[:, 1])
    headings = np.arctan2(d[:, 1], d[:, 0])
    steps: list[Step] = []
    heading, leg = None, 0.0
    for length, yaw in zip(lengths, headings, strict=True):
        if length == 0:
            continue
        turn = 0.0 if heading is None else math.degrees(_wrap(yaw - heading))
        if abs(turn) < MERGE_TURN_DEG:
            leg += length
            heading = yaw if heading is None else heading
            continue
        _close_leg(steps, leg)
        if steps and steps[-1].kind == "turn":  # no leg worth saying since the last turn: one combined turn
            turn = steps.pop().amount + turn
        if abs(turn) >= MERGE_TURN_DEG:
            steps.append(Step("turn", turn))
        heading, leg = yaw, length
    _close_leg(steps, leg)
    while steps and steps[-1].kind == "turn":  # turning on the spot at the goal is not worth saying
        steps.pop()
    return steps


def _close_leg(steps: list[Step], leg: float) -> None:
    if leg >= MIN_LEG_M:
        steps.append(Step("forward", leg))


def _wrap(a: float) -> float:
    return (a + math.pi) % (2 * math.pi) - math.pi


def say_distance(metres: float) -> str:
    """3.1 -> "3 metres", 2.7 -> "about 2.5 metres", 0.4 -> "half a metre", 12.6 -> "about 13 metres"."""
    r = max(0.5, round(metres * 2) / 2 if metres < 10 else float(round(metres)))
    text = "half a metre" if r == 0.5 else "1 metre" if r == 1 else f"{r:g} metres"
    return f"about {text}" if abs(metres - r) > 0.1 else text


def say_turn(degrees: float) -> str:
    """Left for counter-clockwise: 88 -> "turn left about 90 degrees", -25 -> "turn slightly right"."""
    side = "left" if degrees > 0 else "right"
    a = abs(degrees)
    if a >= 160:
        return "turn around"
    if a < 35:
        return f"turn slightly {side}"
    return f"turn {side} about {int(round(a / 15) * 15)} degrees"


def base_action(text: TrajectoryText, rng: np.random.Generator) -> list[Instruction]:
    """One step-by-step instruction for the path; wording varies with `rng`."""
    forward = _FORWARD[rng.integers(len(_FORWARD))]
    stop = _STOP[rng.integers(len(_STOP))]
    clauses: list[str] = []
    pending_turn: str | None = None
    for step in path_steps(text.waypoints):
        if step.kind == "turn":
            if pending_turn:
                clauses.append(pending_turn)
            pending_turn = say_turn(step.amount)
        else:
            walk = f"{forward} {say_distance(step.amount)}"
            clauses.append(f"{pending_turn} and {walk}" if pending_turn else walk)
            pending_turn = None
    if pending_turn:
        clauses.append(pending_turn)
    body = ", ".join(clauses)
    sentence = f"{body}, {stop}." if clauses else "Stop here."
    return [Instruction("low", "Base_Action", _capitalise(sentence), "template")]


def single_goal(text: TrajectoryText, rng: np.random.Generator) -> list[Instruction]:
    """One "from A to B" instruction naming both endpoints; wording varies with `rng`."""
    template = _SINGLE_GOAL[rng.integers(len(_SINGLE_GOAL))]
    at = "in" if text.start_kind == "room" else "at"
    return [Instruction("low", "Single_Goal", _capitalise(template.format(s=text.start_name, g=text.goal_name, at=at)),
                        "template")]


def _capitalise(s: str) -> str:
    return s[:1].upper() + s[1:]
