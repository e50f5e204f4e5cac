"""The LLM prompt for one trajectory (a text map of the scene and the path), kept within a token budget.

Templates live in sagebench/data/prompts/. The scene map lists every room and object with its unique
name, attributes, room and centre, and the objects passed are those a person walking the path would see
(sight.objects_seen: near it, no wall between); when the prompt would exceed the budget, the objects farthest from
the path are left out (never the start, the goal or what the path passes) and the map says how many.
Tokens are estimated as characters / CHARS_PER_TOKEN, on the safe side: the 5-room demo's prompts are
about 7,000 characters, which a real server counted as about 2,100 tokens (3.3 characters a token).
"""

from __future__ import annotations

import json
import math
import string
import tomllib
from functools import cache
from importlib import resources

import numpy as np
import shapely
from shapely.geometry import LineString, Point, Polygon

from sagebench.instructions import high_level as templates
from sagebench.instructions.base import SceneContext, TrajectoryText
from sagebench.instructions.naming import words
from sagebench.instructions.relations import rooms_along
from sagebench.instructions.sight import objects_seen

CHARS_PER_TOKEN = 3.0


class PromptTooLong(Exception):
    """Even the shortest scene map leaves the prompt over its budget."""


@cache
def _prompt_file(name: str) -> str:
    return resources.files("sagebench").joinpath(f"data/prompts/{name}").read_text(encoding="utf-8")


@cache
def _type_texts() -> dict[str, dict[str, str]]:
    return tomllib.loads(_prompt_file("types.toml"))


def estimate_tokens(text: str) -> int:
    return math.ceil(len(text) / CHARS_PER_TOKEN)


def room_lines(ctx: SceneContext) -> list[str]:
    """One line per room: unique name, type and centre (x, y) in metres."""
    out = []
    for r in ctx.rooms:
        c = np.asarray(ctx.room_polygons[r.id], dtype=np.float64).mean(axis=0)
        out.append(f"- {ctx.room_names.get(r.id, 'a ' + words(r.type))} (type: {words(r.type)}), "
                   f"centre ({c[0]:.1f}, {c[1]:.1f})")
    return out


def object_lines(ctx: SceneContext) -> list[tuple[int, str]]:
    """(instance id, line) per object and fixture: unique name, category, attributes, room and centre."""
    out = []
    for o in (*ctx.objects, *ctx.fixtures):
        name = ctx.names.get(o.instance_id, f"a {words(o.category)}")
        attrs = ", ".join(f"{k} {words(v)}" for k, v in sorted(o.attributes.items())) or "no attributes"
        room = f"in {ctx.room_names.get(o.room_id or '', 'no room')}" if o.joins is None else _joins_text(ctx, o.joins)
        pos = ""
        if o.instance_id in ctx.layout:
            x, y = ctx.layout.centroids[ctx.layout.index(o.instance_id)]
            pos = f", at ({x:.1f}, {y:.1f})"
        out.append((o.instance_id, f"- {name}: {words(o.category)}; {attrs}; {room}{pos}"))
    return out


def _joins_text(ctx: SceneContext, joins: tuple[str, ...]) -> str:
    """Where a door is: "joins the study and the kitchen", "joins the kitchen to the outside"."""
    rooms = [ctx.room_names.get(r, "a room") for r in joins]
    return f"joins {' and '.join(rooms)}" if len(rooms) > 1 else f"joins {rooms[0]} to the outside" if rooms \
        else "leads outside"


def build_prompt(kind: str, text: TrajectoryText, budget_tokens: int | None = None) -> str:
    """The prompt asking for one `kind` instruction for this trajectory, within `budget_tokens` (estimated).

    Raises PromptTooLong when leaving out every object not needed still leaves it over the budget.
    """
    ctx = text.scene
    assert ctx is not None
    xy = text.waypoints[:, :2]
    passed_ids = [ctx.layout.ids[j] for j in objects_seen(ctx.layout, xy, ctx.sight)]
    passed = [ctx.names[i] for i in passed_ids if i in ctx.names and i not in (text.start_id, text.goal_id)]
    facts = templates.relation_phrases(ctx, text) if text.goal_id is not None else []
    if text.goal_id is not None and text.goal_room in ctx.local_names:
        local = ctx.local_names[text.goal_room].get(text.goal_id)
        if local:
            facts.append(f"within its room it is {local}")
    seg = np.diff(xy, axis=0)
    spec = _type_texts()[kind]
    fields = dict(
        type_name=kind.replace("_", " "), type_definition=spec["definition"], type_example=spec["example"],
        rooms="\n".join(room_lines(ctx)),
        start=_endpoint(ctx, text.start_name, text.start_room, text.start_kind),
        goal=_endpoint(ctx, text.goal_name, text.goal_room, text.goal_kind),
        rooms_passed=", ".join(ctx.room_names.get(r, "a room") for r in rooms_along(xy, ctx.room_polygons)) or "none",
        objects_passed=", ".join(passed[:12]) or "none",
        length=f"{float(np.hypot(seg[:, 0], seg[:, 1]).sum()):.0f}", goal_facts="; ".join(facts) or "none")
    lines = object_lines(ctx)
    keep = {text.start_id, text.goal_id, *passed_ids}
    droppable = sorted((i for i, (iid, _) in enumerate(lines) if iid not in keep),
                       key=lambda i: -_distance_to_path(ctx, lines[i][0], xy))
    template = string.Template(_prompt_file("high_level.txt"))
    dropped: set[int] = set()
    while True:
        shown = [line for i, (_, line) in enumerate(lines) if i not in dropped]
        if dropped:
            shown.append(f"- ({len(dropped)} more objects, farther from the path, are left out)")
        prompt = template.substitute(objects="\n".join(shown), **fields)
        if budget_tokens is None or estimate_tokens(prompt) <= budget_tokens:
            return prompt
        if len(dropped) == len(droppable):
            raise PromptTooLong(f"the prompt needs about {estimate_tokens(prompt)} tokens, over the budget of "
                                f"{budget_tokens}")
        over = estimate_tokens(prompt) - budget_tokens
        for i in droppable[len(dropped):]:  # farthest first; about one line per 30 tokens over
            dropped.add(i)
            over -= len(lines[i][1]) / CHARS_PER_TOKEN
            if over <= 0:
                break


def _distance_to_path(ctx: SceneContext, instance_id: int, xy: np.ndarray) -> float:
    """Metres from the object's footprint (else its room's floor) to the path [M, 2]."""
    path = LineString(xy) if len(xy) > 1 else Point(xy[0])
    if instance_id in ctx.layout:
        return float(shapely.distance(ctx.layout.geoms[ctx.layout.index(instance_id)], path))
    room = next((o.room_id for o in (*ctx.objects, *ctx.fixtures) if o.instance_id == instance_id), None)
    if room in ctx.room_polygons:
        return float(shapely.distance(Polygon(ctx.room_polygons[room]), path))
    return math.inf


def _endpoint(ctx: SceneContext, name: str, room: str | None, kind: str) -> str:
    if kind == "room":
        return name
    return f"{name}, in {ctx.room_names.get(room or '', 'no room')}"


def exploration_prompt(instruction: str, written: list[str]) -> str:
    """The prompt for one more phrasing of the no-goal instruction, different from those `written` before it."""
    return string.Template(_prompt_file("nogoal.txt")).substitute(
        instruction=instruction, written="\n".join(f"  - {w}" for w in written) or "  - (none yet)")


def retry_prompt(prompt: str, answer: str, problems: list[str]) -> str:
    return string.Template(_prompt_file("retry.txt")).substitute(
        prompt=prompt, answer=answer.strip()[:400], problems="; ".join(problems))


def parse_answer(content: str) -> str | None:
    """The "instruction" string of a JSON answer (code fences and chatter around it are ignored).

    The request stops at the first "}", which the server leaves out of the reply: it is put back.
    """
    lo, hi = content.find("{"), content.rfind("}")
    if lo < 0:
        return None
    body = content[lo:hi + 1] if hi > lo else content[lo:].rstrip() + "}"
    try:
        value = json.loads(body).get("instruction")
    except (ValueError, AttributeError):
        return None
    return " ".join(value.split()) if isinstance(value, str) and value.strip() else None
