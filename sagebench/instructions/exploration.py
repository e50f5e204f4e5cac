"""nogoal's instruction in llm mode: SAGE-Bench's exploration instruction in the chat model's words, one phrasing
per episode of a scene, so that an agent is not trained on, nor tested with, one sentence.

Each phrasing is asked for in turn, its prompt quoting those already written (prompt.exploration_prompt), so a
scene's phrasings differ and a second run reads them all back from the cache. An answer is kept when it still
says both things SAGE's sentence says (explore, and avoid collisions), holds no digit, has 6 to 25 words and
repeats neither SAGE's sentence nor an earlier phrasing; otherwise it is asked again quoting why, and then SAGE's
sentence is kept ("template"), as it is on every row in template mode.
"""

from __future__ import annotations

import re

from sagebench.instructions.llm_client import ChatClient, LLMError
from sagebench.instructions.prompt import exploration_prompt, parse_answer, retry_prompt

EXPLORE = re.compile(r"\b(explor|look around|cover|visit|survey|wander|roam|tour|see as much|as much)", re.I)
AVOID = re.compile(r"\b(avoid|collid|collision|bump|hit|crash|touch|run into|without)", re.I)
WORDS = (6, 25)


def exploration_instructions(client: ChatClient, instruction: str, n: int) -> list[tuple[str, str]]:
    """`n` (text, source) phrasings of `instruction`: the model's ("llm:<model>") or, where none passed, `instruction`
    itself ("template")."""
    written: list[str] = []
    out = []
    for _ in range(n):
        text = _phrasing(client, instruction, written)
        if text is None:
            out.append((instruction, "template"))
        else:
            out.append((text, f"llm:{client.config.model}"))
            written.append(text)
    return out


def _phrasing(client: ChatClient, instruction: str, written: list[str]) -> str | None:
    """One phrasing the checks pass, or None (no answer passed in `answer_attempts`, or no answer came)."""
    prompt = ask = exploration_prompt(instruction, written)
    for _ in range(client.config.answer_attempts):
        try:
            content = client.complete(ask, keep=lambda answer: parse_answer(answer) is not None)
        except LLMError:
            return None
        sentence = parse_answer(content)
        found = problems(sentence, [instruction, *written])
        if not found:
            return sentence
        ask = retry_prompt(prompt, content, found)
    return None


def problems(sentence: str | None, before: list[str]) -> list[str]:
    """Why `sentence` is no phrasing of the exploration instruction distinct from those `before` (empty: it is)."""
    if sentence is None:
        return ["the answer is not JSON with an \"instruction\" string"]
    words = len(sentence.split())
    return [why for bad, why in (
        (not EXPLORE.search(sentence), "it does not tell the robot to explore"),
        (not AVOID.search(sentence), "it does not tell the robot to avoid collisions"),
        (any(c.isdigit() for c in sentence), "it has digits"),
        (not WORDS[0] <= words <= WORDS[1], f"it has {words} words, not {WORDS[0]} to {WORDS[1]}"),
        (_plain(sentence) in map(_plain, before), "it repeats a phrasing already written"),
    ) if bad]


def _plain(text: str) -> str:
    return " ".join(re.sub(r"[^a-z ]", " ", text.lower()).split())
