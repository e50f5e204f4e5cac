"""High-level template instructions of SAGE-Bench's five types, grounded in the semantic map.

Each type describes the goal its own way, and every description picks out exactly one thing:
- Add_Object: bring a carried item to the goal (items per category/room type from scenarios.toml);
- Scenario_Driven: a human need the goal serves (scenarios.toml), narrowed by room or name when needed;
- Relative_Relationship: the goal by a relation to a landmark (next to, between, left/right as seen
  from the start, closest to), or a room by an object in it;
- Attribute_Based: the goal by its colour, material and state;
- Area_Based: the goal's room, then the goal among that room's objects.
Every type that can describe a trajectory's goal offers a sentence (`sentences`, phrasing drawn from the
trajectory's rng). gen-trajectories chooses among them for all the scene's trajectories at once
(`balanced`), so each type's count is its `SceneContext.type_mix` share (default equal) of the trajectories
wherever the goals allow (`balance.balance_types`); a trajectory on its own gets one drawn the same way.
"""

from __future__ import annotations

import tomllib
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from functools import cache
from importlib import resources

import numpy as np

from sagebench.instructions.balance import TypeBalance, balance_types
from sagebench.instructions.base import Instruction, SceneContext, TrajectoryText
from sagebench.instructions.naming import ObjectInfo, door_peers, door_place, words
from sagebench.instructions.relations import NEXT_TO_M, between, nearest, next_to, rooms_along, side_as_seen
from sagebench.settings.gen_trajectories import HIGH_LEVEL_TYPES

_MATERIAL_ADJ = {"wood": "wooden", "wool": "woollen"}
_ADJ_KEYS = (("colour",), ("material",), ("state",), ("colour", "material"), ("state", "colour"),
             ("colour", "material", "state"))
_RELATIONAL = (" in ", " with ", " next to ", " closest to ")  # names built on another thing
_GO = ("Go to {x}.", "Walk over to {x} and stop there.", "Find {x}.", "Head for {x}.", "Make your way to {x}.")


@dataclass(frozen=True)
class Scenario:
    name: str
    categories: tuple[str, ...]
    rooms: tuple[str, ...]
    say: tuple[str, ...]
    purpose: tuple[str, ...]
    only_in: dict[str, tuple[str, ...]]  # category -> room types where it serves the need (others: any room)

    def served_by(self, category: str, room_type: str | None) -> bool:
        """Whether a `category` object in a room of `room_type` serves the need (a bathroom sink is no drink)."""
        return category in self.categories and (category not in self.only_in or room_type in self.only_in[category])


@dataclass(frozen=True)
class Delivery:
    prep: str  # "on", "in", "next to"
    items: tuple[str, ...]  # with article: "a plate"


@cache
def scenario_data() -> tuple[tuple[Scenario, ...], dict[str, Delivery]]:
    """Needs and deliveries from the package file sagebench/data/scenarios.toml."""
    raw = tomllib.loads(resources.files("sagebench").joinpath("data/scenarios.toml").read_text(encoding="utf-8"))
    needs = tuple(Scenario(k, tuple(v["categories"]), tuple(v["rooms"]), tuple(v["say"]), tuple(v["purpose"]),
                           {c: tuple(r) for c, r in v.get("only_in", {}).items()})
                  for k, v in raw["need"].items())
    deliveries = {k: Delivery(v["prep"], tuple(v["items"])) for k, v in raw["add_object"].items()}
    return needs, deliveries


def high_level(text: TrajectoryText, rng: np.random.Generator) -> list[Instruction]:
    """One high-level template instruction for the trajectory (none without a scene)."""
    made = describe(text, rng)
    return [] if made is None else [Instruction("high", made[0], made[1], "template")]


def describe(text: TrajectoryText, rng: np.random.Generator) -> tuple[str, str] | None:
    """(type, sentence): the one chosen with the scene's other trajectories (`text.high_level`), else one drawn
    for this trajectory alone; None when no type can describe the goal."""
    if text.high_level is not None:
        return text.high_level
    (alone,), _ = balanced([text], [rng], rng)
    return alone.high_level


def sentences(text: TrajectoryText, rng: np.random.Generator) -> dict[str, str]:
    """Type -> sentence for every type with a positive share that can describe the goal (phrasings from `rng`)."""
    ctx = text.scene
    if ctx is None:
        return {}
    out = {}
    for kind in HIGH_LEVEL_TYPES:
        sentence = _TYPES[kind](ctx, text, rng) if ctx.type_mix.get(kind, 0) > 0 else None
        if sentence is not None:
            out[kind] = _capitalise(sentence)
    return out


def balanced(texts: Sequence[TrajectoryText], rngs: Sequence[np.random.Generator],
             rng: np.random.Generator) -> tuple[list[TrajectoryText], TypeBalance]:
    """The trajectories of one scene with their high-level (type, sentence) chosen together: every type's count
    is its share of `type_mix` wherever the goals allow. Phrasings come from `rngs` (one per trajectory), the
    choice from `rng`."""
    offered = [sentences(t, r) for t, r in zip(texts, rngs, strict=True)]
    mix = texts[0].scene.type_mix if texts and texts[0].scene is not None else {}  # one scene: one mix
    balance = balance_types([o.keys() for o in offered], mix, rng)
    return [replace(t, high_level=None if k is None else (k, o[k]))
            for t, o, k in zip(texts, offered, balance.chosen)], balance


def _pick(rng: np.random.Generator, options):
    return options[int(rng.integers(len(options)))]


# ---------------------------------------------------------------- the five types


def add_object(ctx: SceneContext, text: TrajectoryText, rng: np.random.Generator) -> str | None:
    _, deliveries = scenario_data()
    if text.goal_id is not None:
        delivery, target = deliveries.get(ctx.object(text.goal_id).category), ctx.names.get(text.goal_id)
    else:
        room = _room(ctx, text.goal_room)
        delivery, target = deliveries.get(room.type) if room else None, ctx.room_names.get(text.goal_room or "")
    if delivery is None or target is None:
        return None
    item = _pick(rng, delivery.items)
    return _pick(rng, (
        f"Put {item} {delivery.prep} {target}.",
        f"Take {item} to {target} and leave it there.",
        f"Bring {item} over to {target}.",
        f"Carry {item} to {target} for me.",
    ))


def scenario_driven(ctx: SceneContext, text: TrajectoryText, rng: np.random.Generator) -> str | None:
    needs, _ = scenario_data()
    if text.goal_id is not None:
        goal = ctx.object(text.goal_id)
        fits = [n for n in needs if n.served_by(goal.category, _room_type(ctx, goal.room_id))]
    else:
        room = _room(ctx, text.goal_room)
        fits = [n for n in needs if room is not None and room.type in n.rooms]
    if not fits:
        return None
    need = _pick(rng, fits)
    say, purpose = _pick(rng, need.say), _pick(rng, need.purpose)
    if text.goal_id is not None:
        serving = [o for o in ctx.objects if need.served_by(o.category, _room_type(ctx, o.room_id))]
        in_room = [o for o in serving if o.room_id == goal.room_id]
        if len(serving) == 1:
            return _pick(rng, (f"{say} Go where I can {purpose}.", f"{say} Take me to where I can {purpose}."))
        if len(in_room) == 1 and goal.room_id in ctx.room_names:
            return f"{say} In {ctx.room_names[goal.room_id]}, find where I can {purpose}."
        name = ctx.names.get(goal.instance_id)
        return None if name is None else f"{say} Go to {name} so I can {purpose}."
    serving_rooms = [r for r in ctx.rooms if r.type in need.rooms]
    if len(serving_rooms) == 1:
        return _pick(rng, (f"{say} Go to the room where I can {purpose}.",
                           f"{say} Take me to the room where I can {purpose}."))
    name = ctx.room_names.get(text.goal_room or "")
    return None if name is None else f"{say} Go to {name} so I can {purpose}."


def relative_relationship(ctx: SceneContext, text: TrajectoryText, rng: np.random.Generator) -> str | None:
    if text.goal_id is None:
        holders = [n for i, n in ctx.names.items()
                   if ctx.object(i).room_id == text.goal_room and ctx.object(i).category != "door"
                   and not any(w in n for w in _RELATIONAL)]
        if not holders:
            return None
        x = _pick(rng, sorted(holders))
        return _pick(rng, (f"Go to the room with {x}.", f"Enter the room that has {x} in it.",
                           f"Find the room where {x} stands and go in."))
    options = relation_phrases(ctx, text)
    if not options:
        return None
    return _pick(rng, _GO).format(x=_pick(rng, options))


def relation_phrases(ctx: SceneContext, text: TrajectoryText) -> list[str]:
    """Every relational description that picks out the goal object among its category."""
    lay = ctx.layout
    goal = ctx.object(text.goal_id)
    peers = [o for o in ctx.objects if o.category == goal.category]
    if len(peers) == 1 or goal.instance_id not in lay or not all(p.instance_id in lay for p in peers):
        return []  # the only one of its category needs no relation to single it out
    noun, i = words(goal.category), lay.index(goal.instance_id)
    peer_idx = [lay.index(p.instance_id) for p in peers]
    marks = {lay.index(k): n for k, n in ctx.names.items()
             if k in lay and not any(w in n for w in _RELATIONAL)
             and ctx.object(k).category != goal.category and ctx.object(k).room_id == goal.room_id}
    out: list[str] = []
    near = [j for j in next_to(lay, i) if j in marks]
    for j in near:
        if sum(lay.gaps[p, j] <= NEXT_TO_M for p in peer_idx) == 1:
            out.append(f"the {noun} next to {marks[j]}")
    for a_pos, a in enumerate(near):
        for b in near[a_pos + 1:]:
            if between(lay, i, a, b) and sum(between(lay, p, a, b) for p in peer_idx) == 1:
                out.append(f"the {noun} between {marks[a]} and {marks[b]}")
    start = text.waypoints[0, :2]
    for j in near:
        side = side_as_seen(start, lay.centroids[j], lay.centroids[i])
        rivals = [p for p in peer_idx if lay.gaps[p, j] <= NEXT_TO_M
                  and side_as_seen(start, lay.centroids[j], lay.centroids[p]) == side]
        if side is not None and rivals == [i]:
            out.append(f"the {noun} on the {side} of {marks[j]} as seen from where you start")
    for j in sorted(marks, key=lambda j: lay.gaps[i, j]):
        if lay.gaps[i, j] <= NEXT_TO_M * 3 and nearest(lay, peer_idx, j) == i:
            out.append(f"the {noun} closest to {marks[j]}")
            break
    return out


def attribute_based(ctx: SceneContext, text: TrajectoryText, rng: np.random.Generator) -> str | None:
    if text.goal_id is None:
        return None
    goal = ctx.object(text.goal_id)
    peers = [o for o in ctx.objects if o.category == goal.category]
    noun, suffix = words(goal.category), ""
    if _distinguishing(goal, peers) is None:
        if goal.joins is not None:  # a door is placed by the rooms it joins
            place = door_place(goal, ctx.room_names)
            local = door_peers(goal, peers)
            if place is None or _distinguishing(goal, local) is None:
                return None
            noun, suffix = place
        else:
            local = [o for o in peers if o.room_id == goal.room_id]
            if _distinguishing(goal, local) is None or goal.room_id not in ctx.room_names:
                return None
            suffix = f" in {ctx.room_names[goal.room_id]}"
    a = goal.attributes
    colour, material, state = (words(a[k]) if a.get(k) else None for k in ("colour", "material", "state"))
    if not (colour or material or state):
        return None
    adj = " ".join(w for w in (state, colour, _MATERIAL_ADJ.get(material or "", material)) if w)
    descs = [f"the {adj} {noun}{suffix}"]
    if material and (colour or state) and not suffix:
        descs.append(f"the {' '.join(w for w in (state, colour) if w)} {noun}{suffix} made of {material}")
    if colour and not state and not material:
        descs.append(f"the {noun}{suffix} that is {colour}")
    return _pick(rng, _GO).format(x=_pick(rng, descs))


def area_based(ctx: SceneContext, text: TrajectoryText, rng: np.random.Generator) -> str | None:
    room = ctx.room_names.get(text.goal_room or "")
    if room is None:
        return None
    if text.goal_id is None:
        passed = [r for r in rooms_along(text.waypoints[:, :2], ctx.room_polygons)[1:-1]
                  if r != text.goal_room and r in ctx.room_names]
        options = [f"Go to {room}.", f"Head into {room} and stop there.", f"Make your way into {room}."]
        if passed:
            options.append(f"Go through {ctx.room_names[passed[0]]} into {room}.")
        return _pick(rng, options)
    local = ctx.local_names.get(text.goal_room or "", {}).get(text.goal_id)
    if local is None:
        return None
    return _pick(rng, (f"Go to {room} and stop at {local}.", f"In {room}, find {local}.",
                       f"Head into {room} and wait by {local}.", f"Enter {room} and go to {local}."))


_TYPES: dict[str, Callable[[SceneContext, TrajectoryText, np.random.Generator], str | None]] = {
    "Add_Object": add_object,
    "Scenario_Driven": scenario_driven,
    "Relative_Relationship": relative_relationship,
    "Attribute_Based": attribute_based,
    "Area_Based": area_based,
}


def _distinguishing(obj: ObjectInfo, pool: list[ObjectInfo]) -> tuple[str, ...] | None:
    """Attribute keys whose values single `obj` out of `pool` (() when it is alone), else None."""
    if len(pool) == 1:
        return ()
    for keys in _ADJ_KEYS:
        if all(obj.attributes.get(k) for k in keys):
            want = tuple(obj.attributes[k] for k in keys)
            if sum(tuple(o.attributes.get(k) for k in keys) == want for o in pool) == 1:
                return keys
    return None


def _room(ctx: SceneContext, room_id: str | None):
    return next((r for r in ctx.rooms if r.id == room_id), None)


def _room_type(ctx: SceneContext, room_id: str | None) -> str | None:
    room = _room(ctx, room_id)
    return None if room is None else room.type


def _capitalise(s: str) -> str:
    return s[:1].upper() + s[1:]
