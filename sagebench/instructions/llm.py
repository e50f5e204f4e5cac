"""High-level instructions from an OpenAI-compatible chat model, grounded or replaced by the template.

`ChatClient` speaks POST {base_url}/chat/completions with the standard library only (vLLM, a
llama.cpp server, Ollama and OpenAI all serve that route). It bounds concurrent requests, times out,
retries 429/5xx/timeouts/connection errors with exponential backoff (honouring Retry-After), and
caches every answer on disk under sha256(model, prompt), so regenerating a run is reproducible and
sends no request. `LLMInstructor` asks for one instruction of the type the template draw chose,
checks it with `grounding.Grounder`, asks again quoting the problems, and otherwise keeps the
template sentence (`instruction_source` "template" instead of "llm:<model>").
"""

from __future__ import annotations

import hashlib
import ipaddress
import json
import os
import string
import threading
import time
import tomllib
import urllib.error
import urllib.parse
import urllib.request
from collections import Counter
from dataclasses import replace
from functools import cache
from importlib import resources
from pathlib import Path
import numpy as np
from pydantic import BaseModel, ConfigDict, Field, field_validator

from sagebench.fileio import dumps_json, write_text
from sagebench.instructions import high_level as templates
from sagebench.instructions.base import Instruction, SceneContext, TrajectoryText
from sagebench.instructions.grounding import Grounder
from sagebench.instructions.naming import words
from sagebench.instructions.relations import objects_passed, rooms_along

RETRY_STATUS = frozenset({408, 409, 425, 429, 500, 502, 503, 504})
MAX_RETRY_AFTER_S = 30.0


class LLMConfig(BaseModel):
    """The chat model and how to call it (defaults here, nowhere else)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    base_url: str | None = Field(default=None, description="OpenAI-compatible API root, e.g. http://localhost:8000/v1.")
    model: str | None = Field(default=None, description="Model name sent with each request.")
    api_key_env: str = Field(default="SAGEBENCH_LLM_API_KEY", description="Environment variable holding the API key.")
    cache_dir: Path | None = Field(default=None, description="Answer cache (default: the user cache directory).")
    concurrency: int = Field(default=4, ge=1, le=64, description="Requests in flight at once.")
    timeout_s: float = Field(default=60.0, gt=0, description="Per-request timeout, s.")
    max_attempts: int = Field(default=4, ge=1, description="HTTP attempts per request (429, 5xx, timeouts retried).")
    backoff_s: float = Field(default=1.0, ge=0, description="First retry delay, s; doubles per attempt.")
    answer_attempts: int = Field(default=2, ge=1, description="Answers asked for before the template is kept.")
    temperature: float = Field(default=0.0, ge=0, description="Sampling temperature sent with each request.")

    @field_validator("base_url")
    @classmethod
    def _http_url(cls, url: str | None) -> str | None:
        parsed = urllib.parse.urlparse(url or "http://x")
        if parsed.scheme not in ("http", "https") or not parsed.hostname:
            raise ValueError(f"must be an http(s) URL such as http://localhost:8000/v1, got {url!r}")
        return url


class LLMError(Exception):
    """A request failed for good (after retries, or with a status not worth retrying)."""


def default_cache_dir() -> Path:
    import platformdirs

    return Path(platformdirs.user_cache_dir("sagebench")) / "llm"


class ChatClient:
    """Thread-safe chat-completions client with a disk cache; `stats` counts requests, hits, retries."""

    def __init__(self, config: LLMConfig):
        if not config.base_url or not config.model:
            raise ValueError("LLMConfig needs base_url and model")
        parsed = urllib.parse.urlparse(config.base_url)
        self.config = config
        self.url = config.base_url.rstrip("/") + "/chat/completions"
        self.cache_dir = Path(config.cache_dir) if config.cache_dir is not None else default_cache_dir()
        self._slots = threading.BoundedSemaphore(config.concurrency)
        self._lock = threading.Lock()
        self.stats: Counter[str] = Counter()
        proxies = {} if _is_loopback(parsed.hostname) else None  # never send loopback traffic to a proxy
        self._opener = urllib.request.build_opener(urllib.request.ProxyHandler(proxies))
        key = os.environ.get(config.api_key_env, "")
        self._headers = {"Content-Type": "application/json", **({"Authorization": f"Bearer {key}"} if key else {})}

    def cache_path(self, prompt: str) -> Path:
        key = hashlib.sha256(json.dumps([self.config.model, prompt]).encode()).hexdigest()
        return self.cache_dir / key[:2] / f"{key}.json"

    def complete(self, prompt: str) -> str:
        """The model's reply to `prompt` (one user message), from the cache when it was asked before."""
        path = self.cache_path(prompt)
        if path.is_file():
            self._count("cache_hits")
            return json.loads(path.read_text(encoding="utf-8"))["content"]
        content = self._request(prompt)
        write_text(path, dumps_json({"model": self.config.model, "prompt": prompt, "content": content}))
        return content

    def _request(self, prompt: str) -> str:
        cfg = self.config
        body = json.dumps({"model": cfg.model, "messages": [{"role": "user", "content": prompt}],
                           "temperature": cfg.temperature, "seed": 0}).encode()
        last = "no attempt"
        for attempt in range(cfg.max_attempts):
            if attempt:
                self._count("retries")
            wait = cfg.backoff_s * 2**attempt
            try:
                with self._slots:
                    self._count("requests")
                    req = urllib.request.Request(self.url, data=body, headers=self._headers, method="POST")
                    with self._opener.open(req, timeout=cfg.timeout_s) as resp:
                        payload = resp.read()
            except urllib.error.HTTPError as err:
                detail = err.read()[:200].decode("utf-8", "replace")
                last = f"HTTP {err.code} {detail}".strip()
                if err.code not in RETRY_STATUS:
                    raise LLMError(f"{self.url}: {last}") from None
                wait = max(wait, _retry_after(err.headers.get("Retry-After")))
            except (urllib.error.URLError, TimeoutError, ConnectionError, OSError) as err:
                last = f"{type(err).__name__}: {getattr(err, 'reason', err)}"
            else:
                try:
                    return json.loads(payload)["choices"][0]["message"]["content"]
                except (ValueError, KeyError, IndexError, TypeError):
                    raise LLMError(f"{self.url}: not a chat-completions response: {payload[:200]!r}") from None
            if attempt + 1 < cfg.max_attempts:
                time.sleep(wait)
        raise LLMError(f"{self.url}: {last} (after {cfg.max_attempts} attempts)")

    def _count(self, key: str) -> None:
        with self._lock:
            self.stats[key] += 1


def _is_loopback(host: str) -> bool:
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def _retry_after(value: str | None) -> float:
    try:
        return min(max(float(value), 0.0), MAX_RETRY_AFTER_S) if value else 0.0
    except ValueError:
        return 0.0


# ---------------------------------------------------------------- prompts


@cache
def _prompt_file(name: str) -> str:
    return resources.files("sagebench").joinpath(f"data/prompts/{name}").read_text(encoding="utf-8")


@cache
def _type_texts() -> dict[str, dict[str, str]]:
    return tomllib.loads(_prompt_file("types.toml"))


def scene_map(ctx: SceneContext) -> tuple[str, str]:
    """(rooms, objects): one line each, with unique names, attributes, room and centre (x, y) in metres."""
    rooms = []
    for r in ctx.rooms:
        poly = np.asarray(ctx.room_polygons[r.id], dtype=np.float64)
        c = poly.mean(axis=0)
        rooms.append(f"- {ctx.room_names.get(r.id, 'a ' + words(r.type))} (type: {words(r.type)}), "
                     f"centre ({c[0]:.1f}, {c[1]:.1f})")
    objects = []
    for o in (*ctx.objects, *ctx.fixtures):
        name = ctx.names.get(o.instance_id, f"a {words(o.category)}")
        attrs = ", ".join(f"{k} {words(v)}" for k, v in sorted(o.attributes.items())) or "no attributes"
        room = ctx.room_names.get(o.room_id or "", "no room")
        pos = ""
        if o.instance_id in ctx.layout:
            x, y = ctx.layout.centroids[ctx.layout.index(o.instance_id)]
            pos = f", at ({x:.1f}, {y:.1f})"
        objects.append(f"- {name}: {words(o.category)}; {attrs}; in {room}{pos}")
    return "\n".join(rooms), "\n".join(objects)


def build_prompt(kind: str, text: TrajectoryText) -> str:
    """The prompt asking for one `kind` instruction for this trajectory (from data/prompts/high_level.txt)."""
    ctx = text.scene
    assert ctx is not None
    rooms, objects = scene_map(ctx)
    xy = text.waypoints[:, :2]
    passed_rooms = [ctx.room_names.get(r, "a room") for r in rooms_along(xy, ctx.room_polygons)]
    passed = [ctx.names[ctx.layout.ids[j]] for j in objects_passed(ctx.layout, xy)
              if ctx.layout.ids[j] in ctx.names and ctx.layout.ids[j] not in (text.start_id, text.goal_id)]
    facts = templates.relation_phrases(ctx, text) if text.goal_id is not None else []
    if text.goal_id is not None and text.goal_room in ctx.local_names:
        local = ctx.local_names[text.goal_room].get(text.goal_id)
        if local:
            facts.append(f"within its room it is {local}")
    seg = np.diff(xy, axis=0)
    spec = _type_texts()[kind]
    return string.Template(_prompt_file("high_level.txt")).substitute(
        type_name=kind.replace("_", " "), type_definition=spec["definition"], type_example=spec["example"],
        rooms=rooms, objects=objects,
        start=_endpoint(ctx, text.start_name, text.start_room, text.start_kind),
        goal=_endpoint(ctx, text.goal_name, text.goal_room, text.goal_kind),
        rooms_passed=", ".join(passed_rooms) or "none", objects_passed=", ".join(passed[:12]) or "none",
        length=f"{float(np.hypot(seg[:, 0], seg[:, 1]).sum()):.0f}", goal_facts="; ".join(facts) or "none")


def _endpoint(ctx: SceneContext, name: str, room: str | None, kind: str) -> str:
    if kind == "room":
        return name
    return f"{name}, in {ctx.room_names.get(room or '', 'no room')}"


def retry_prompt(prompt: str, answer: str, problems: list[str]) -> str:
    return string.Template(_prompt_file("retry.txt")).substitute(
        prompt=prompt, answer=answer.strip()[:400], problems="; ".join(problems))


def parse_answer(content: str) -> str | None:
    """The "instruction" string of a JSON answer (code fences and chatter around it are ignored)."""
    lo, hi = content.find("{"), content.rfind("}")
    if lo < 0 or hi <= lo:
        return None
    try:
        value = json.loads(content[lo:hi + 1]).get("instruction")
    except (ValueError, AttributeError):
        return None
    return " ".join(value.split()) if isinstance(value, str) and value.strip() else None


# ---------------------------------------------------------------- the generator


class LLMInstructor:
    """Asks the model for one scene's high-level instructions; shared by the threads of that scene."""

    def __init__(self, client: ChatClient, ctx: SceneContext):
        self.client = client
        self.grounder = Grounder(ctx)
        self.source = f"llm:{client.config.model}"
        self.stats: Counter[str] = Counter()  # llm, fallback, and one entry per rejection reason kind
        self.errors: list[str] = []
        self._lock = threading.Lock()

    def high_level(self, text: TrajectoryText, rng: np.random.Generator) -> list[Instruction]:
        made = templates.describe(text, rng)
        if made is None:
            return []
        kind, fallback = made
        prompt = build_prompt(kind, text)
        ctx = text.scene
        goal = ctx.object(text.goal_id) if text.goal_id is not None else None
        room_type = next((r.type for r in ctx.rooms if r.id == text.goal_room), None) if goal is None else None
        need_goal = kind != "Scenario_Driven"
        ask = prompt
        for _ in range(self.client.config.answer_attempts if not self._unreachable() else 0):
            try:
                content = self.client.complete(ask)
            except LLMError as err:
                self._note("request failed", str(err))
                break
            sentence = parse_answer(content)
            problems = ["the answer is not JSON with an \"instruction\" string"] if sentence is None else \
                self.grounder.problems(sentence, goal_category=goal.category if goal and need_goal else None,
                                       goal_room_type=room_type if need_goal else None)
            if not problems:
                self._note("llm")
                return [Instruction("high", kind, sentence, self.source)]
            self._note("rejected")
            ask = retry_prompt(prompt, content, problems)
        self._note("fallback")
        return [Instruction("high", kind, fallback, "template")]

    def _unreachable(self) -> bool:
        """Three failed requests and no answer yet: stop asking, keep the templates (summary warns)."""
        with self._lock:
            return self.stats["request failed"] >= 3 and not (self.stats["llm"] or self.stats["rejected"])

    def _note(self, key: str, error: str | None = None) -> None:
        with self._lock:
            self.stats[key] += 1
            if error is not None and len(self.errors) < 3:
                self.errors.append(error)

    def summary(self) -> str:
        s, c = self.stats, self.client.stats
        failed = f"; {s['request failed']} failed requests, e.g. {self.errors[0]}" if self.errors else ""
        return (f"{s['llm']} LLM answers used, {s['fallback']} template fallbacks ({s['rejected']} answers rejected "
                f"by the grounding check); {c['requests']} requests, {c['cache_hits']} from cache{failed}")


def llm_high_level(text: TrajectoryText, rng: np.random.Generator) -> list[Instruction]:
    """The "llm" mode's high-level generator: the scene's LLMInstructor, or the template without one."""
    instructor = None if text.scene is None else text.scene.llm
    if instructor is None:
        return templates.high_level(text, rng)
    return instructor.high_level(text, rng)


def with_instructor(ctx: SceneContext, config: LLMConfig) -> tuple[SceneContext, LLMInstructor]:
    """`ctx` carrying a fresh instructor (its own client and counters) for one scene."""
    instructor = LLMInstructor(ChatClient(config), ctx)
    return replace(ctx, llm=instructor), instructor
