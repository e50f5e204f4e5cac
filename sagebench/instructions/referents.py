"""Reading instruction text into the noun phrases it refers with (the parse half of the grounding check).

Mentions are found by longest match against the scene's categories and room types, their synonyms and
a vocabulary of other furniture and room words (sagebench/data/vocabulary.toml), plural or singular;
"room" alone is a room of any type. A phrase is a mention with the attribute words before it and the
modifiers after it, read left to right:

    [the] [bright] red wooden sofa   that is red | made of wood   in the living room
    ... next to | beside | by | near X      between X and Y (objects, or rooms a door joins)      closest to X
    ... on the left of | to the right of X      (rooms:) with | that has | containing | where X

A phrase that modifies another (a landmark, a room placement) is not a top-level phrase. Each
top-level phrase has a role from the word before it: "via" after past, through, from, leave ...,
"scope" for a room after in, into, inside, enter, to ..., else "target".
"""

from __future__ import annotations

import re
import tomllib
from collections.abc import Iterable
from dataclasses import dataclass
from functools import cache
from importlib import resources

from sagebench.instructions.base import SceneContext
from sagebench.instructions.high_level import scenario_data
from sagebench.instructions.naming import words

_TOKEN = re.compile(r"[a-z]+(?:'[a-z]+)?")
DETERMINERS = ("the", "a", "an")
INTENSIFIERS = frozenset({"bright", "dark", "light", "pale", "deep", "very"})
VIA = frozenset({"past", "passing", "through", "via", "from", "leave", "leaving", "exit", "exiting", "across",
                 "around", "behind", "beyond"})
SCOPE = frozenset({"in", "into", "inside", "enter", "entering", "within", "to"})
POST_ATTR = (("that", "is"), ("which", "is"), ("that's",), ("painted",), ("coloured",), ("colored",), ("made", "of"))
IN_ROOM = (("in",), ("inside",), ("within",))
RELATIONS = (
    ("next_to", (("next", "to"), ("beside",), ("by",), ("near",), ("near", "to"), ("close", "to"), ("alongside",))),
    ("between", (("between",),)),  # two objects, or two rooms ("joins": a door between the kitchen and the hall)
    ("closest_to", (("closest", "to"), ("nearest", "to"), ("nearest",), ("closest",))),
    ("left", (("on", "the", "left", "of"), ("to", "the", "left", "of"), ("left", "of"))),
    ("right", (("on", "the", "right", "of"), ("to", "the", "right", "of"), ("right", "of"))),
)
CONTAINS = (("with",), ("that", "has"), ("that", "contains"), ("containing",), ("where",), ("that", "holds"))
_APOSTROPHE_ENDINGS = frozenset({"s", "m", "re", "ll", "d", "ve"})


@dataclass(frozen=True)
class Vocabulary:
    objects: tuple[str, ...]  # phrases with spaces
    rooms: tuple[str, ...]
    attributes: tuple[str, ...]
    synonyms: dict[str, str]  # word or phrase -> snake_case category / room type / attribute value
    general: frozenset[str]  # words that name nothing: verbs, prepositions, pronouns ...


@cache
def vocabulary() -> Vocabulary:
    raw = tomllib.loads(resources.files("sagebench").joinpath("data/vocabulary.toml").read_text(encoding="utf-8"))
    return Vocabulary(tuple(raw["objects"]), tuple(raw["rooms"]), tuple(raw["attributes"]), dict(raw["synonyms"]),
                      frozenset(raw["general"]))


@dataclass(frozen=True)
class Mention:
    kind: str  # "object" or "room"
    phrase: str  # as written (singular), e.g. "dining table"
    adjectives: tuple[str, ...]  # canonical attribute values written before it, e.g. ("red", "wood")
    matches: frozenset[str]  # categories or room types it may refer to
    start: int  # token index of its first adjective (of the noun when none)
    head: int  # token index of the noun
    end: int  # token index after the noun


@dataclass(frozen=True, eq=False)
class Phrase:
    mention: Mention
    attrs: tuple[str, ...]  # canonical attribute values before or after the noun
    room: Phrase | None  # "in the kitchen"
    relation: str | None  # next_to | between | joins | closest_to | left | right
    landmarks: tuple[Phrase, ...]
    contains: Phrase | None  # a room's "with the desk"
    text: str  # the words as written with their article, for messages ("the sofa in the kitchen")
    base: str  # the adjectives and the noun as written ("green chair")

    @property
    def bare(self) -> str:
        """The words without a leading article ("sofa in the kitchen")."""
        first, _, rest = self.text.partition(" ")
        return rest if first in DETERMINERS and rest else self.text


class Reader:
    """Tokens, mentions and known words of one scene (read-only once built)."""

    def __init__(self, ctx: SceneContext):
        vocab = vocabulary()
        self._canon = dict(vocab.synonyms)
        things = [*ctx.objects, *ctx.fixtures]
        categories = {o.category for o in things}
        room_types = {r.type for r in ctx.rooms}
        heads: dict[str, set[str]] = {}
        for cat in categories:
            heads.setdefault(words(cat).split()[-1], set()).add(cat)
        def canon(phrase: str) -> str:
            return self._canon.get(phrase, phrase.replace(" ", "_"))

        # a scene category or room type that is itself a synonym ("hallway") still matches what it names
        same = {c: canon(words(c)) for c in categories | room_types}
        self._objects: dict[tuple[str, ...], frozenset[str]] = {}
        for phrase in {*vocab.objects, *(words(c) for c in categories)}:
            generic = heads.get(phrase, set()) if " " not in phrase else set()
            self._objects[tuple(phrase.split())] = frozenset(
                {canon(phrase), *generic, *(c for c in categories if same[c] == canon(phrase))})
        for phrase, value in vocab.synonyms.items():
            if value in categories or phrase in vocab.objects:
                self._objects.setdefault(tuple(phrase.split()), frozenset({value}))
        self._rooms: dict[tuple[str, ...], frozenset[str]] = {("room",): frozenset(room_types)}
        for phrase in {*vocab.rooms, *(words(t) for t in room_types)}:
            self._rooms[tuple(phrase.split())] = frozenset({canon(phrase), *(t for t in room_types
                                                                             if same[t] == canon(phrase))})
        values = {w for o in things for v in o.attributes.values() for w in words(v).lower().split()}
        self._attr_words = frozenset({*vocab.attributes, *values})
        self._longest = max(len(p) for p in [*self._objects, *self._rooms])
        self.known = frozenset(vocab.general | self._attr_words | INTENSIFIERS | _scene_words(ctx, vocab)
                               | {w for p in [*self._objects, *self._rooms] for w in p})

    @staticmethod
    def tokens(text: str) -> list[str]:
        return _TOKEN.findall(text.lower())

    def canonical(self, value: str) -> str:
        v = words(value).lower()
        return self._canon.get(v, v)

    def mentions(self, toks: list[str]) -> list[Mention]:
        """Object and room mentions, left to right, longest phrase first."""
        out: list[Mention] = []
        k = 0
        while k < len(toks):
            hit = None
            for n in range(min(self._longest, len(toks) - k), 0, -1):
                for span in _singulars(toks[k:k + n]):
                    if span in self._objects:
                        hit = ("object", span, self._objects[span])
                    elif span in self._rooms:
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
            while j >= 0 and kind == "object" and (toks[j] in self._attr_words or toks[j] in INTENSIFIERS) and \
                    (not out or j >= out[-1].end):
                if toks[j] not in INTENSIFIERS:
                    adjs.insert(0, self.canonical(toks[j]))
                j -= 1
            out.append(Mention(kind, " ".join(span), tuple(adjs), matches, j + 1, k, k + len(span)))
            k += len(span)
        return out

    def read_attrs(self, toks: list[str], pos: int) -> tuple[tuple[str, ...], int]:
        """Attribute words from `pos` on ("bright red", "red and white"): canonical values, position after."""
        vals: list[str] = []
        while pos < len(toks) and (toks[pos] in self._attr_words or toks[pos] in INTENSIFIERS
                                   or (vals and toks[pos] in ("and", "or"))):
            if toks[pos] in self._attr_words:
                vals.append(self.canonical(toks[pos]))
            pos += 1
        return tuple(vals), pos

    def forms(self, tok: str) -> list[str]:
        """The token and the words it may be an inflection of ("walking" -> walk, "stopped" -> stop)."""
        out = [tok]
        if "'" in tok:
            base, _, end = tok.partition("'")
            if end in _APOSTROPHE_ENDINGS:
                out.append(base)
        for cut, add in (("ies", "y"), ("ves", "f"), ("es", ""), ("s", ""), ("ed", ""), ("ed", "e"), ("d", ""),
                         ("ing", ""), ("ing", "e"), ("ly", ""), ("ier", "y"), ("iest", "y"), ("er", ""), ("est", "")):
            if tok.endswith(cut) and len(tok) > len(cut) + 2:
                stem = tok[: -len(cut)] + add
                out.append(stem)
                if not add and len(stem) > 2 and stem[-1] == stem[-2]:
                    out.append(stem[:-1])  # "stopped" -> "stopp" -> "stop"
        return out

    def unknown_words(self, toks: list[str], mentions: Iterable[Mention]) -> set[str]:
        """Words outside the mentions that are neither scene words nor general words."""
        covered = {k for m in mentions for k in range(m.start, m.end)}
        return {t for k, t in enumerate(toks) if k not in covered and not any(f in self.known for f in self.forms(t))}


def _scene_words(ctx: SceneContext, vocab: Vocabulary) -> set[str]:
    """Words of the scene's names and of what people say in the scenarios (needs, carried items)."""
    needs, deliveries = scenario_data()
    texts = [*(n for n in ctx.names.values()), *ctx.room_names.values(), *vocab.synonyms,
             *(s for n in needs for s in (n.name, *n.say, *n.purpose)),
             *(i for d in deliveries.values() for i in d.items)]
    return {w for t in texts for w in Reader.tokens(t)}


def parse(toks: list[str], mentions: list[Mention], reader: Reader) -> list[tuple[Phrase, str]]:
    """The top-level phrases of the text with their roles ("target", "scope" or "via"), left to right."""
    by_start = {m.start: k for k, m in enumerate(mentions)}
    consumed: set[int] = set()

    def seq_at(pos: int, options: tuple[tuple[str, ...], ...]) -> int | None:
        for opt in sorted(options, key=len, reverse=True):
            if tuple(toks[pos:pos + len(opt)]) == opt:
                return pos + len(opt)
        return None

    def mention_at(pos: int | None, kind: str) -> int | None:
        if pos is None:
            return None
        while pos < len(toks) and toks[pos] in DETERMINERS:
            pos += 1
        k = by_start.get(pos)
        return k if k is not None and mentions[k].kind == kind and k not in consumed else None

    def phrase(k: int) -> tuple[Phrase, int]:
        consumed.add(k)
        m = mentions[k]
        pos, attrs = m.end, list(m.adjectives)
        room = contains = None
        relation, landmarks = None, ()
        while pos < len(toks):
            after = seq_at(pos, POST_ATTR)
            if after is not None:
                vals, end = reader.read_attrs(toks, after)
                if vals:
                    attrs.extend(vals)
                    pos = end
                    continue
            if m.kind == "object" and room is None:
                r = mention_at(seq_at(pos, IN_ROOM), "room")
                if r is not None:
                    room, pos = phrase(r)
                    continue
            if m.kind == "object" and relation is None:
                found = _relation(pos)
                if found is not None:
                    relation, landmarks, pos = found
                    continue
            if m.kind == "room" and contains is None:
                c = mention_at(seq_at(pos, CONTAINS), "object")
                if c is not None:
                    contains, pos = phrase(c)
                    continue
            break
        first = m.start - 1 if m.start > 0 and toks[m.start - 1] in DETERMINERS else m.start
        text = " ".join(toks[first:pos])
        base = " ".join(toks[m.start:m.end])
        return Phrase(m, tuple(attrs), room, relation, tuple(landmarks), contains, text, base), pos

    def _relation(pos: int):
        for name, options in RELATIONS:
            start = seq_at(pos, options)
            for kind in ("object", "room") if name == "between" else ("object",):
                a = mention_at(start, kind)
                if a is None:
                    continue
                before = set(consumed)
                first, end = phrase(a)
                if name != "between":
                    return name, (first,), end
                b = mention_at(end + 1 if end < len(toks) and toks[end] == "and" else None, kind)
                if b is None:
                    consumed.intersection_update(before)
                    continue
                second, end = phrase(b)
                return ("between" if kind == "object" else "joins"), (first, second), end
        return None

    out: list[tuple[Phrase, str]] = []
    for k, m in enumerate(mentions):
        if k in consumed:
            continue
        p, _ = phrase(k)
        out.append((p, _role(toks, m)))
    return out


def _role(toks: list[str], m: Mention) -> str:
    j = m.start - 1
    while j >= 0 and toks[j] in DETERMINERS:
        j -= 1
    before = toks[j] if j >= 0 else ""
    if before in VIA or (before == "of" and j > 0 and toks[j - 1] == "out"):
        return "via"
    if m.kind == "room" and before in SCOPE:
        return "scope"
    return "target"


def _singulars(span: list[str]) -> Iterable[tuple[str, ...]]:
    """The span as written, then with its last word made singular ("chairs", "benches", "shelves")."""
    yield tuple(span)
    last = span[-1]
    for cut, add in (("ies", "y"), ("ves", "f"), ("es", ""), ("s", "")):
        if last.endswith(cut) and len(last) > len(cut) + 2:
            yield (*span[:-1], last[: -len(cut)] + add)
