"""High-level instructions from an OpenAI-compatible chat model, grounded or replaced by the template.

`LLMInstructor` asks `llm_client.ChatClient` for one instruction of the type chosen for the trajectory,
checks it with `grounding.Grounder`, asks again quoting the problems, and otherwise keeps the
template sentence (`instruction_source` "template" instead of "llm:<model>"). Once the client's
breaker has opened, every remaining trajectory keeps its template without a request.
"""

from __future__ import annotations

import threading
from collections import Counter
from dataclasses import dataclass, replace

import numpy as np

from sagebench.instructions import high_level as templates
from sagebench.instructions.base import Instruction, SceneContext, TrajectoryText
from sagebench.instructions.grounding import Grounder, reason
from sagebench.instructions.llm_client import ChatClient, LLMError, LLMUnavailable
from sagebench.instructions.prompt import PromptTooLong, build_prompt, parse_answer, retry_prompt
from sagebench.settings.gen_trajectories import LLMConfig


@dataclass(frozen=True)
class LLMShare:
    """How many high-level rows came from the model, and whether that meets the configured minimum."""

    llm: int
    total: int
    min_share: float

    @property
    def share(self) -> float:
        return self.llm / self.total if self.total else 1.0

    @property
    def enough(self) -> bool:
        return self.total == 0 or (self.llm > 0 and self.share >= self.min_share)

    def line(self) -> str:
        return (f"{self.llm} of {self.total} high-level rows from the model ({100 * self.share:.0f} %), "
                f"{self.total - self.llm} template")


class LLMInstructor:
    """Asks the model for one scene's high-level instructions; shared by the threads of that scene."""

    def __init__(self, client: ChatClient, ctx: SceneContext):
        self.client = client
        self.grounder = Grounder(ctx)
        self.source = f"llm:{client.config.model}"
        self.stats: Counter[str] = Counter()  # llm, fallback, rejected, request failed, not asked, over budget
        self.rejections: Counter[str] = Counter()  # rejected answers by the reason of their first problem
        self.errors: list[str] = []
        self._lock = threading.Lock()

    def high_level(self, text: TrajectoryText, rng: np.random.Generator) -> list[Instruction]:
        made = templates.describe(text, rng)
        if made is None:
            return []
        kind, fallback = made
        try:
            prompt = build_prompt(kind, text, self.client.config.prompt_tokens)
        except PromptTooLong as err:
            self._note("over budget", str(err))
            return self._fallback(kind, fallback)
        ask = prompt
        for _ in range(self.client.config.answer_attempts):
            try:
                content = self.client.complete(ask, keep=lambda answer: parse_answer(answer) is not None)
            except LLMUnavailable:
                self._note("not asked")
                break
            except LLMError as err:
                self._note("request failed", str(err))
                break
            sentence = parse_answer(content)
            problems = ["the answer is not JSON with an \"instruction\" string"] if sentence is None else \
                self.grounder.problems(sentence, goal_id=text.goal_id, goal_room=text.goal_room, kind=kind,
                                       start_xy=text.waypoints[0, :2])
            if not problems:
                self._note("llm")
                return [Instruction("high", kind, sentence, self.source)]
            self._note("rejected", reason=reason(problems[0]))
            ask = retry_prompt(prompt, content, problems)
        return self._fallback(kind, fallback)

    def _fallback(self, kind: str, sentence: str) -> list[Instruction]:
        self._note("fallback")
        return [Instruction("high", kind, sentence, "template")]

    def _note(self, key: str, error: str | None = None, *, reason: str | None = None) -> None:
        with self._lock:
            self.stats[key] += 1
            if reason is not None:
                self.rejections[reason] += 1
            if error is not None and len(self.errors) < 3:
                self.errors.append(error)

    def share(self) -> LLMShare:
        s = self.stats
        return LLMShare(s["llm"], s["llm"] + s["fallback"], self.client.config.min_share)

    def summary(self) -> str:
        s, c = self.stats, self.client.stats
        why = ", ".join(f"{n} {r}" for r, n in sorted(self.rejections.items(), key=lambda rn: (-rn[1], rn[0])))
        parts = [self.share().line(), f"{s['rejected']} answers rejected by the grounding check" + (f" ({why})" if why else ""),
                 f"{c['requests']} requests, {c['cache_hits']} from cache"]
        if s["request failed"]:
            parts.append(f"{s['request failed']} failed requests, e.g. {self.errors[0]}")
        if s["over budget"]:
            parts.append(f"{s['over budget']} prompts over the budget of {self.client.config.prompt_tokens} tokens")
        if self.client.breaker.reason:
            parts.append(f"{self.client.breaker.reason}; {s['not asked']} trajectories not asked")
        return "; ".join(parts)


def llm_high_level(text: TrajectoryText, rng: np.random.Generator) -> list[Instruction]:
    """The "llm" mode's high-level generator: the scene's LLMInstructor, or the template without one."""
    instructor = None if text.scene is None else text.scene.llm
    if instructor is None:
        return templates.high_level(text, rng)
    return instructor.high_level(text, rng)


def with_instructor(ctx: SceneContext, config: LLMConfig, *, api_key: str | None = None
                    ) -> tuple[SceneContext, LLMInstructor]:
    """`ctx` carrying a fresh instructor (its own client, breaker and counters) for one scene; the client's
    concurrency is settled here (ChatClient.discover_concurrency), before any thread asks."""
    client = ChatClient(config, api_key=api_key)
    client.discover_concurrency()
    instructor = LLMInstructor(client, ctx)
    return replace(ctx, llm=instructor), instructor
