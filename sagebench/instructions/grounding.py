"""Grounding check of instruction text against a scene: every object and room it names must exist.

Mentions are found by longest match against the scene's categories and room types, their synonyms
and a vocabulary of other furniture and room words (sagebench/data/vocabulary.toml), plural or
singular. A mention must match something in the scene; colour, material or state words written
right before an object noun must match one object of that kind. Internal ids ("room_3", "#41"),
snake_case names and numbers (coordinates included) are rejected outright. The problems are
returned as short phrases that a retry prompt can quote back to the model.
"""

from __future__ import annotations

import re
import tomllib
from collections.abc import Iterable
from dataclasses import dataclass
from functools import cache
from importlib import resources

from sagebench.instructions.base import SceneContext
from sagebench.instructions.naming import words

MIN_WORDS, MAX_WORDS = 4, 30
_TOKEN = re.compile(r"[a-z]+(?:'[a-z]+)?")
_ID = re.compile(r"[A-Za-z]_?\d|\d_|#\s*\d|\b(?:id|instance|object|room)\s*[:#=]?\s*\d", re.IGNORECASE)
_COORD = re.compile(r"\d+\.\d+|\d+\s*,\s*-?\d+")
_SNAKE = re.compile(r"\b[a-z]+_[a-z_]+\b", re.IGNORECASE)


@dataclass(frozen=True)
class Vocabulary:
    objects: tuple[str, ...]  # phrases with spaces
    rooms: tuple[str, ...]
    attributes: tuple[str, ...]
    synonyms: dict[str, str]  # word or phrase -> snake_case category / room type / attribute value


@cache
def vocabulary() -> Vocabulary:
    raw = tomllib.loads(resources.files("sagebench").joinpath("data/vocabulary.toml").read_text(encoding="utf-8"))
    return Vocabulary(tuple(raw["objects"]), tuple(raw["rooms"]), tuple(raw["attributes"]), dict(raw["synonyms"]))


@dataclass(frozen=True)
class Mention:
    kind: str  # "object" or "room"
    phrase: str  # as written (singular), e.g. "dining table"
    adjectives: tuple[str, ...]  # canonical attribute values written before it, e.g. ("red", "wood")
    matches: frozenset[str]  # categories or room types it may refer to


class Grounder:
    """Checks texts against one scene (built once per scene, then shared by threads: read-only)."""

    def __init__(self, ctx: SceneContext):
        vocab = vocabulary()
        self._canon = {k: v for k, v in vocab.synonyms.items()}
        things = [*ctx.objects, *ctx.fixtures]
        self.categories = frozenset(o.category for o in things)
        self.room_types = frozenset(r.type for r in ctx.rooms)
        self._attrs: dict[str, list[frozenset[str]]] = {}
        for o in things:
            self._attrs.setdefault(o.category, []).append(frozenset(self._value(v) for v in o.attributes.values()))
        heads: dict[str, set[str]] = {}
        for cat in self.categories:
            heads.setdefault(words(cat).split()[-1], set()).add(cat)
        self._objects: dict[tuple[str, ...], frozenset[str]] = {}
        for phrase in {*vocab.objects, *(words(c) for c in self.categories)}:
            canon = self._canon.get(phrase, phrase.replace(" ", "_"))
            generic = heads.get(phrase, set()) if " " not in phrase else set()
            self._objects[tuple(phrase.split())] = frozenset({canon, *generic})
        for phrase, canon in vocab.synonyms.items():
            if canon in self.categories or phrase in vocab.objects:
                self._objects.setdefault(tuple(phrase.split()), frozenset({canon}))
        self._rooms: dict[tuple[str, ...], frozenset[str]] = {}
        for phrase in {*vocab.rooms, *(words(t) for t in self.room_types)}:
            self._rooms[tuple(phrase.split())] = frozenset({self._canon.get(phrase, phrase.replace(" ", "_"))})
        self._attr_words = frozenset({*vocab.attributes, *(v for vals in self._attrs.values() for s in vals for v in s)})
        self._longest = max(len(p) for p in [*self._objects, *self._rooms])

    def _value(self, v: str) -> str:
        v = words(v).lower()
        return self._canon.get(v, v)

    def mentions(self, text: str) -> list[Mention]:
        """Object and room mentions in `text`, left to right, longest phrase first."""
        toks = _TOKEN.findall(text.lower())
        out: list[Mention] = []
        k = 0
        while k < len(toks):
            hit = None
            for n in range(min(self._longest, len(toks) - k), 0, -1):
                for span in _singulars(toks[k:k + n]):
                    if span in self._objects:
                        hit = ("object", span, self._objects[span])
                    elif span in self._rooms and span != ("room",):
                        hit = ("room", span, self._rooms[span])
                    if hit:
                        break
                if hit:
                    break
            if hit is None:
                k += 1
                continue
            kind, span, matches = hit
            adjs: list[str] = []
            j = k - 1
            while j >= 0 and toks[j] in self._attr_words and kind == "object":
                adjs.insert(0, self._value(toks[j]))
                j -= 1
            out.append(Mention(kind, " ".join(span), tuple(adjs), matches))
            k += len(span)
        return out

    def problems(self, text: str, *, goal_category: str | None = None, goal_room_type: str | None = None) -> list[str]:
        """Why `text` is not grounded in the scene ([] when it is).

        With `goal_category` (or `goal_room_type` for a room goal) the text must also mention the goal
        (a room may also be "the room" described by what is in it).
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
        mentions = self.mentions(text)
        for m in mentions:
            if m.kind == "room":
                if not m.matches & self.room_types:
                    found.append(f"there is no {m.phrase} in this scene")
                continue
            cats = m.matches & self.categories
            if not cats:
                found.append(f"there is no {m.phrase} in this scene")
            elif m.adjectives and not any(set(m.adjectives) <= s for c in cats for s in self._attrs[c]):
                found.append(f"there is no {' '.join(m.adjectives)} {m.phrase} in this scene")
        if goal_category is not None and not any(goal_category in m.matches for m in mentions if m.kind == "object"):
            found.append(f"it does not mention the goal, {words(goal_category)}")
        said_room = any(goal_room_type in m.matches for m in mentions if m.kind == "room") or \
            bool(re.search(r"\brooms?\b", text, re.IGNORECASE))  # "the room with the desk" names it by contents
        if goal_room_type is not None and not said_room:
            found.append(f"it does not mention the goal, {words(goal_room_type)}")
        return found


def _singulars(span: list[str]) -> Iterable[tuple[str, ...]]:
    """The span as written, then with its last word made singular ("chairs", "benches", "shelves")."""
    yield tuple(span)
    last = span[-1]
    for cut, add in (("ies", "y"), ("ves", "f"), ("es", ""), ("s", "")):
        if last.endswith(cut) and len(last) > len(cut) + 2:
            yield (*span[:-1], last[: -len(cut)] + add)
