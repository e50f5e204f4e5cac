"""Grounding check of instruction text against a scene: what it names must exist, be true, and pick out the goal.

The text is read as noun phrases (`referents.parse`): an object or room word with the attribute words
around it and what follows it ("in the kitchen", "next to the stove", "between A and B", "closest to X",
"on the left of X", "that is red", and for rooms "with the desk"). Each phrase is resolved to the things
of the scene it is true of, by the relations the templates name things with (relations.next_to,
between, nearest, side_as_seen); a phrase true of nothing is a problem ("there is no sofa in the
kitchen in this scene"). Given the goal, the destination (the last phrase not introduced by "past",
"through", "from" ...), taken within the room a preceding "in/into/to the <room>" names and, for
Scenario_Driven, narrowed by the need the text voices (scenarios.toml, as the templates use it), must
be exactly the goal; a Scenario_Driven text must voice a need the goal serves. Words that are neither
scene words nor general words (vocabulary.toml), spelled-out numbers, internal ids ("room_3", "#41"),
snake_case names, coordinates and digits are rejected. Problems are short phrases that a retry prompt
can quote back to the model.
"""

from __future__ import annotations

import re
from collections.abc import Iterable

import numpy as np
from sagebench.instructions.base import SceneContext
from sagebench.instructions.high_level import scenario_data
from sagebench.instructions.naming import ObjectInfo, is_outside, words
from sagebench.instructions.referents import Mention, Phrase, Reader, parse, vocabulary
from sagebench.instructions.relations import NEXT_TO_M, between, nearest, side_as_seen

MIN_WORDS, MAX_WORDS = 4, 30
_ID = re.compile(r"[A-Za-z]_?\d|\d_|#\s*\d|\b(?:id|instance|object|room)\s*[:#=]?\s*\d", re.IGNORECASE)
_COORD = re.compile(r"\d+\.\d+|\d+\s*,\s*-?\d+")
_SNAKE = re.compile(r"\b[a-z]+_[a-z_]+\b", re.IGNORECASE)
NUMBER_WORDS = frozenset(
    "two three four five six seven eight nine ten eleven twelve thirteen fourteen fifteen sixteen seventeen eighteen "
    "nineteen twenty thirty forty fifty sixty hundred thousand second third fourth fifth sixth seventh eighth ninth "
    "tenth".split())


class Grounder:
    """Checks texts against one scene (built once per scene, then shared by threads: read-only)."""

    def __init__(self, ctx: SceneContext):
        self.ctx = ctx
        self.things: tuple[ObjectInfo, ...] = (*ctx.objects, *ctx.fixtures)
        self.room_type = {r.id: r.type for r in ctx.rooms}
        self.reader = Reader(ctx)
        self._values = {o.instance_id: self._attr_values(o) for o in self.things}
        # a door is in every room it joins; anything else in its annotated room
        self._rooms_of = {o.instance_id: frozenset(o.joins if o.joins is not None else (o.room_id,)) - {None}
                          for o in self.things}
        self._joins = {o.instance_id: frozenset(o.joins) for o in self.things if o.joins is not None}
        needs, _ = scenario_data()
        self.needs = {n.name: n for n in needs}
        self._need_words = _need_words(needs, self.reader)

    def _attr_values(self, o: ObjectInfo) -> frozenset[str]:
        vals = {self.reader.canonical(v) for v in o.attributes.values()} | ({"outside"} if is_outside(o) else set())
        return frozenset(vals | {w for v in vals for w in v.split()})

    def mentions(self, text: str) -> list[Mention]:
        """Object and room mentions in `text`, left to right, longest phrase first."""
        return self.reader.mentions(self.reader.tokens(text))

    def problems(self, text: str, *, goal_id: int | None = None, goal_room: str | None = None,
                 kind: str | None = None, start_xy: np.ndarray | None = None) -> list[str]:
        """Why `text` is not grounded in the scene ([] when it is).

        goal_id (an object) or goal_room alone (a room goal): the text must send the agent there and
        nowhere else; kind "Scenario_Driven" also needs a need the goal serves; start_xy [2] world metres
        is where "left"/"right" are seen from.
        """
        found: list[str] = []
        if _ID.search(text) or _SNAKE.search(text):
            found.append("it contains an internal id or name")
        elif _COORD.search(text):
            found.append("it contains coordinates")
        elif re.search(r"\d", text):
            found.append("it contains a number")
        n_words = len(text.split())
        if not MIN_WORDS <= n_words <= MAX_WORDS:
            found.append(f"it is {n_words} words long, not {MIN_WORDS}-{MAX_WORDS}")
        toks = self.reader.tokens(text)
        mentions = self.reader.mentions(toks)
        numbers = [t for t in toks if t in NUMBER_WORDS] + \
            [f"{toks[m.head]} one" for m in mentions if m.end < len(toks) and toks[m.end] == "one"]
        if numbers:
            found.append(f"it contains a number ({', '.join(dict.fromkeys(numbers))})")
        unknown = self.reader.unknown_words(toks, mentions) - NUMBER_WORDS
        if unknown:
            found.append(f"it names things that are not in the scene map: {', '.join(sorted(unknown))}")
        phrases = parse(toks, mentions, self.reader)
        resolver = _Resolver(self, start_xy)
        for phrase, _ in phrases:
            resolver.resolve(phrase)
        found.extend(dict.fromkeys(resolver.problems))
        if kind is not None:
            found.extend(type_problems(kind, toks, phrases))
        if goal_id is not None or goal_room is not None:
            found.extend(self._goal_problems(toks, phrases, resolver, goal_id, goal_room, kind))
        return found

    # ------------------------------------------------------------ the goal

    def _goal_problems(self, toks: list[str], phrases: list[tuple[Phrase, str]], resolver: _Resolver,
                       goal_id: int | None, goal_room: str | None, kind: str | None) -> list[str]:
        ctx = self.ctx
        goal_name = ctx.names.get(goal_id, "the goal") if goal_id is not None else ctx.room_names.get(goal_room, "the goal room")
        out: list[str] = []
        fitting: list[str] = []
        if kind == "Scenario_Driven":
            voiced = self.voiced_needs(toks)
            fitting = [n for n in voiced if self._serves(n, goal_id, goal_room)]
            if not voiced:
                out.append(f"it voices no need that {goal_name} serves")
            elif not fitting:
                out.append(f"the need it voices ({', '.join(voiced)}) is not one that {goal_name} serves")
        targets = [(p, role) for p, role in phrases if role != "via"]
        dest = targets[-1][0] if targets else None
        if dest is None:
            if not fitting:
                return [*out, f"it does not say where to go: name the goal, {goal_name}"]
            cands = self._serving(fitting, goal_id is not None, None)
            where = "the place it asks for"
        else:
            where = dest.text
            cands = resolver.resolve(dest)
            scope = self._scope(targets, dest, resolver)
            if scope is not None:
                if dest.mention.kind == "object" and dest.room is None:
                    cands = {i for i in cands if self._rooms(i) & scope}
                if not cands:
                    return [*out, f"there is no {dest.bare} in {scope_text(targets, dest)}"]
            if dest.mention.kind == "room" and goal_id is not None:
                if not fitting:
                    return [*out, f"it sends the robot to {dest.text}, a room, but the goal is {goal_name}"]
                cands = self._serving(fitting, True, cands)
            elif dest.mention.kind == "object" and goal_id is None:
                return [*out, f"it sends the robot to {dest.text}, but the goal is {goal_name}, a room"]
            elif fitting and len(cands) > 1:
                cands = cands & self._serving(fitting, goal_id is not None, None)
        want = goal_id if goal_id is not None else goal_room
        if not cands and dest is not None and not resolver.resolve(dest):
            return out  # "there is no ..." says it already
        if cands == {want}:
            return out
        if want in cands:
            return [*out, f"{where} could be any of {len(cands)} places; say which one is meant ({goal_name})"]
        return [*out, f"it sends the robot to {where}, but the goal is {goal_name}"]

    def voiced_needs(self, toks: list[str]) -> list[str]:
        """The needs (scenarios.toml) whose words the text uses most, in table order ([] when none)."""
        score = {name: sum(1 for t in toks for f in self.reader.forms(t) if f in ws) for name, ws in
                 self._need_words.items()}
        best = max(score.values(), default=0)
        return [n for n, s in score.items() if s == best] if best else []

    def _serves(self, need: str, goal_id: int | None, goal_room: str | None) -> bool:
        n = self.needs[need]
        if goal_id is not None:
            obj = self.ctx.object(goal_id)
            return n.served_by(obj.category, self.room_type.get(obj.room_id or ""))
        return self.room_type.get(goal_room or "") in n.rooms

    def _serving(self, needs: list[str], objects: bool, rooms: set | None) -> set:
        """Objects (or rooms) serving any of `needs`; objects only in `rooms` when given."""
        if objects:
            return {o.instance_id for o in self.ctx.objects if any(self._serves(n, o.instance_id, None) for n in needs)
                    and (rooms is None or o.room_id in rooms)}
        return {r.id for r in self.ctx.rooms if any(self._serves(n, None, r.id) for n in needs)}

    def _scope(self, targets: list[tuple[Phrase, str]], dest: Phrase, resolver: _Resolver) -> set[str] | None:
        room = _scope_phrase(targets, dest)
        return None if room is None else resolver.resolve(room)

    def _rooms(self, instance_id: int) -> frozenset[str]:
        """The rooms the thing is in: a door's are the rooms it joins."""
        return self._rooms_of.get(instance_id, frozenset())


CARRY_WORDS = frozenset({"put", "take", "bring", "carry", "leave", "deliver", "drop", "place", "set"})
TYPE_NEEDS = {  # what a text of each type must do besides reaching the goal (Scenario_Driven's need: _goal_problems)
    "Add_Object": "ask for something to be carried there",
    "Relative_Relationship": "single the goal out by where it is against something else (next to, between, on the "
                             "left or right of, closest to, the room with)",
    "Attribute_Based": "single the goal out by its colour, material or state",
    "Area_Based": "name the room it is in",
}


def type_problems(kind: str, toks: list[str], phrases: list[tuple[Phrase, str]]) -> list[str]:
    """Why a text is not of the instruction type `kind` ([] when it is, or the type asks nothing checkable here)."""
    every = [q for p, _ in phrases for q in _nested(p)]
    fits = {
        "Add_Object": lambda: bool(CARRY_WORDS & set(toks)),
        "Relative_Relationship": lambda: any(q.relation is not None or q.contains is not None for q in every),
        "Attribute_Based": lambda: any(q.attrs for q in every if q.mention.kind == "object"),
        "Area_Based": lambda: any(q.mention.kind == "room" for q in every),
    }.get(kind)
    if fits is None or fits():
        return []
    return [f"it is not a {kind.replace('_', ' ')} instruction: it must {TYPE_NEEDS[kind]}"]


def _nested(p: Phrase) -> list[Phrase]:
    """`p` and every phrase inside it (its room, landmarks, contents)."""
    inner = [*([p.room] if p.room else []), *p.landmarks, *([p.contains] if p.contains else [])]
    return [p, *(q for i in inner for q in _nested(i))]


# Each problem message above, by the reason a summary groups it under (first match wins).
REASONS = (
    ("not JSON", re.compile(r"^the answer is not JSON")),
    ("internal id, coordinates or number", re.compile(r"^it contains ")),
    ("length", re.compile(r"^it is \d+ words long")),
    ("wrong instruction type", re.compile(r"^it is not an? [A-Z]")),
    ("unknown words", re.compile(r"^it names things that are not in the scene map")),
    ("names what is not there", re.compile(r"^there is no ")),
    ("need", re.compile(r"^(it voices no need|the need it voices)")),
    ("no destination", re.compile(r"^it does not say where to go")),
    ("ambiguous goal", re.compile(r" could be any of \d+ places")),
    ("wrong goal", re.compile(r"^it sends the robot to ")),
)


def reason(problem: str) -> str:
    """The reason a problem message is grouped under in summaries ("other" for none of REASONS)."""
    return next((name for name, pattern in REASONS if pattern.search(problem)), "other")


def _scope_phrase(targets: list[tuple[Phrase, str]], dest: Phrase) -> Phrase | None:
    """The last room phrase before `dest` that sends the agent into a room ("in/into/to the kitchen")."""
    rooms = [p for p, role in targets if role == "scope" and p is not dest and p.mention.kind == "room"
             and p.mention.start < dest.mention.start]
    return rooms[-1] if rooms else None


def scope_text(targets: list[tuple[Phrase, str]], dest: Phrase) -> str:
    room = _scope_phrase(targets, dest)
    return "" if room is None else room.text


class _Resolver:
    """Phrase -> the set of instance ids (objects) or room ids (rooms) it is true of, noting empty ones."""

    def __init__(self, grounder: Grounder, start_xy: np.ndarray | None):
        self.g = grounder
        self.start = start_xy
        self.problems: list[str] = []
        self._memo: dict[int, set] = {}

    def resolve(self, p: Phrase) -> set:
        key = id(p)
        if key not in self._memo:
            self._memo[key] = self._resolve(p)
        return self._memo[key]

    def _resolve(self, p: Phrase) -> set:
        g, m = self.g, p.mention
        if m.kind == "room":
            rooms = {r.id for r in g.ctx.rooms if r.type in m.matches}
            if p.contains is not None:
                inner = self.resolve(p.contains)
                if not inner:
                    return set()
                rooms = {r for r in rooms if any(r in g._rooms(i) for i in inner)}
            if not rooms:
                self.problems.append(f"there is no {p.bare} in this scene")
            return rooms
        cands = [o for o in g.things if o.category in m.matches
                 and set(p.attrs[:len(m.adjectives)]) <= g._values[o.instance_id]]
        if not cands:  # the noun and the adjectives before it already fit nothing: say just that
            self.problems.append(f"there is no {p.base} in this scene")
            return set()
        cands = [o for o in cands if set(p.attrs) <= g._values[o.instance_id]]
        if p.room is not None:
            rooms = self.resolve(p.room)
            if not rooms:
                return set()
            cands = [o for o in cands if g._rooms(o.instance_id) & rooms]
        ids = {o.instance_id for o in cands}
        if p.relation is not None and ids:
            marks = [self.resolve(lm) for lm in p.landmarks]
            if not all(marks):
                return set()
            ids = self._related(p.relation, [o.instance_id for o in cands], marks)
        if not ids:
            self.problems.append(f"there is no {p.bare} in this scene")
        return ids

    def _related(self, relation: str, cands: list[int], marks: list[set]) -> set[int]:
        """The candidates in `relation` to the landmarks; a relation the footprints cannot check narrows nothing."""
        lay = self.g.ctx.layout
        located = [c for c in cands if c in lay]
        idx = {c: lay.index(c) for c in located}
        if relation == "joins":  # a door between two rooms: it joins both (relations.rooms_joined)
            ra, rb = marks
            joins = self.g._joins
            return {c for c in cands if c in joins and any({x, y} <= joins[c] for x in ra for y in rb if x != y)}
        lms = [[lay.index(i) for i in sorted(ms) if i in lay] for ms in marks]
        if not located or not all(lms):
            return set(cands)
        out = set(c for c in cands if c not in lay)  # unlocated heads stay candidates
        if relation == "next_to":
            out |= {c for c in located if any(lay.gaps[idx[c], j] <= NEXT_TO_M for j in lms[0])}
        elif relation == "between":
            out |= {c for c in located if any(between(lay, idx[c], a, b) for a in lms[0] for b in lms[1])}
        elif relation == "closest_to":
            out |= {lay.ids[k] for j in lms[0] if (k := nearest(lay, list(idx.values()), j)) is not None}
        elif relation in ("left", "right") and self.start is not None:
            out |= {c for c in located for j in lms[0] if lay.gaps[idx[c], j] <= NEXT_TO_M
                    and side_as_seen(self.start, lay.centroids[j], lay.centroids[idx[c]]) == relation}
        elif relation in ("left", "right"):
            out |= set(located)  # no viewpoint given: nothing to check the side against
        return out


def _need_words(needs: Iterable, reader: Reader) -> dict[str, frozenset[str]]:
    """Per need, the words of its name, sayings and purposes that are neither general words nor scene nouns."""
    out: dict[str, frozenset[str]] = {}
    common = vocabulary().general
    for n in needs:
        text = " ".join([n.name, *n.say, *n.purpose])
        toks = reader.tokens(text)
        ws = {f for t in toks for f in reader.forms(t)[:1] if f not in common}
        out[n.name] = frozenset(ws | {words(n.name)})
    return out
