"""LLM mode against a fake chat-completions server on 127.0.0.1 (started here; no other network is used).

Covers a good answer, malformed JSON, a hallucinated object (template fallback), a timeout, 429 then
success, 5xx until the attempts run out, and the cache (a second run sends no request, same bytes).
"""

import json
import re
import shutil
import threading
import time
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer

import numpy as np
import pytest

from sagebench.instructions.base import TrajectoryText, make_context
from sagebench.instructions.llm import ChatClient, LLMConfig, LLMError, LLMInstructor, build_prompt, parse_answer
from sagebench.instructions.naming import ObjectInfo, RoomInfo

MAX_REQUESTS = 200  # a runaway client gets 500s past this, and the test that caused it fails


class FakeLLM:
    """POST /v1/chat/completions; `respond(prompt, n)` -> (status, body dict or str, delay s, headers)."""

    def __init__(self, respond):
        self.respond = respond
        self.prompts: list[str] = []
        self.lock = threading.Lock()
        fake = self

        class Handler(BaseHTTPRequestHandler):
            def do_POST(self):  # noqa: N802 (http.server's name)
                body = json.loads(self.rfile.read(int(self.headers["Content-Length"])))
                assert self.path == "/v1/chat/completions" and body["model"] == "fake"
                with fake.lock:
                    fake.prompts.append(body["messages"][0]["content"])
                    n = len(fake.prompts)
                status, payload, delay, headers = (500, "too many requests in a test", 0, {}) if n > MAX_REQUESTS \
                    else fake.respond(fake.prompts[-1], n)
                time.sleep(delay)
                if isinstance(payload, dict):
                    payload = {"choices": [{"message": {"role": "assistant", "content": json.dumps(payload)}}]}
                data = (json.dumps(payload) if not isinstance(payload, str) else payload).encode()
                try:
                    self.send_response(status)
                    for k, v in headers.items():
                        self.send_header(k, v)
                    self.send_header("Content-Length", str(len(data)))
                    self.end_headers()
                    self.wfile.write(data)
                except (BrokenPipeError, ConnectionResetError):
                    pass  # the client timed out and left

            def log_message(self, *args):
                pass

        self.server = ThreadingHTTPServer(("127.0.0.1", 0), Handler)
        self.server.daemon_threads = True
        self.url = f"http://127.0.0.1:{self.server.server_address[1]}/v1"
        self.thread = threading.Thread(target=self.server.serve_forever, daemon=True)
        self.thread.start()

    def close(self):
        self.server.shutdown()
        self.server.server_close()


@pytest.fixture
def fake_llm():
    servers = []

    def start(respond):
        servers.append(FakeLLM(respond))
        return servers[-1]

    yield start
    for s in servers:
        s.close()
    assert all(len(s.prompts) <= MAX_REQUESTS for s in servers)


def goal_answer(prompt: str) -> dict:
    """A grounded answer: go to the goal by the unique name the prompt gives."""
    goal = re.search(r"^- goal: (.*?)(?:, in .*)?$", prompt, re.M).group(1)
    return {"instruction": f"Please go to {goal} and wait there."}


def _config(tmp_path, url, **kw):
    return LLMConfig(base_url=url, model="fake", cache_dir=tmp_path / "cache", backoff_s=0.01, **kw)


# ---------------------------------------------------------------- the client


def test_good_answer_is_returned_and_cached_by_model_and_prompt(fake_llm, tmp_path):
    server = fake_llm(lambda p, n: (200, {"instruction": f"echo {p}"}, 0, {}))
    client = ChatClient(_config(tmp_path, server.url))
    assert json.loads(client.complete("hello"))["instruction"] == "echo hello"
    assert json.loads(client.complete("hello"))["instruction"] == "echo hello"
    assert len(server.prompts) == 1 and client.stats["cache_hits"] == 1
    assert client.cache_path("hello").is_file() and client.cache_path("hello") != client.cache_path("hello!")
    other = ChatClient(LLMConfig(base_url=server.url, model="other", cache_dir=tmp_path / "cache"))
    assert other.cache_path("hello") != client.cache_path("hello")  # the model is part of the key


def test_429_is_retried_after_the_servers_delay(fake_llm, tmp_path):
    server = fake_llm(lambda p, n: (429, {"error": "slow down"}, 0, {"Retry-After": "0"}) if n == 1
                      else (200, {"instruction": "ok"}, 0, {}))
    client = ChatClient(_config(tmp_path, server.url))
    assert json.loads(client.complete("x")) == {"instruction": "ok"}
    assert len(server.prompts) == 2 and client.stats["retries"] == 1


def test_a_timeout_is_retried(fake_llm, tmp_path):
    server = fake_llm(lambda p, n: (200, {"instruction": "late"}, 1.5 if n == 1 else 0, {}))
    client = ChatClient(_config(tmp_path, server.url, timeout_s=0.3))
    assert json.loads(client.complete("x")) == {"instruction": "late"}
    assert len(server.prompts) == 2


def test_5xx_until_the_attempts_run_out_raises_and_caches_nothing(fake_llm, tmp_path):
    server = fake_llm(lambda p, n: (503, {"error": "down"}, 0, {}))
    client = ChatClient(_config(tmp_path, server.url, max_attempts=3))
    t0 = time.perf_counter()
    with pytest.raises(LLMError, match=r"HTTP 503 .* \(after 3 attempts\)"):
        client.complete("x")
    assert len(server.prompts) == 3 and time.perf_counter() - t0 >= 0.03  # backoff 0.01 + 0.02
    assert not client.cache_path("x").exists()


def test_a_client_error_is_not_retried(fake_llm, tmp_path):
    server = fake_llm(lambda p, n: (400, {"error": "bad model"}, 0, {}))
    with pytest.raises(LLMError, match="HTTP 400"):
        ChatClient(_config(tmp_path, server.url)).complete("x")
    assert len(server.prompts) == 1


def test_parse_answer_tolerates_fences_and_rejects_non_json():
    assert parse_answer('```json\n{"instruction": "Go to  the sofa."}\n```') == "Go to the sofa."
    assert parse_answer("Go to the sofa.") is None
    assert parse_answer('{"instruction": 3}') is None
    assert parse_answer('{"instruction": "unterminated}') is None


# ---------------------------------------------------------------- the instructor (grounding, retry, fallback)


@pytest.fixture(scope="module")
def scene():
    objects = [ObjectInfo(1, "sofa", "l", {"colour": "grey", "material": "leather"}),
               ObjectInfo(2, "fridge", "k", {"colour": "black"}), ObjectInfo(3, "dining_table", "k", {"colour": "white"})]
    rooms = [RoomInfo("l", "living_room"), RoomInfo("k", "kitchen")]
    polys = {"l": np.array([(0, 0), (5, 0), (5, 4), (0, 4)], float), "k": np.array([(5, 0), (9, 0), (9, 4), (5, 4)], float)}
    boxes = {1: (1, 1, 3, 2), 2: (8, 3, 8.7, 3.8), 3: (6, 1, 7, 2)}
    feet = {i: [np.array([(a, b), (c, b), (c, d), (a, d)], float)] for i, (a, b, c, d) in boxes.items()}
    ctx = make_context(objects, rooms, polys, feet, type_mix={"Attribute_Based": 1.0})
    wps = np.array([[2.0, 2.5, 0, 0], [6.0, 2.5, 0, 0], [7.5, 3.0, 0, 0]])
    return ctx, TrajectoryText(wps, "the sofa", "the fridge", "object", "object", 1, 2, "l", "k", ctx)


def test_prompt_holds_the_scene_map_and_the_trajectory(scene):
    ctx, text = scene
    prompt = build_prompt("Attribute_Based", text)
    assert "- the fridge: fridge; colour black; in the kitchen, at (8.3, 3.4)" in prompt
    assert "- goal: the fridge, in the kitchen" in prompt and "- start: the sofa, in the living room" in prompt
    assert "rooms passed, in order: the living room, the kitchen" in prompt
    assert "objects passed, in order: the dining table" in prompt
    assert "Attribute Based" in prompt and '{"instruction"' in prompt


def test_a_grounded_answer_is_used_with_the_model_as_source(fake_llm, tmp_path, scene):
    ctx, text = scene
    server = fake_llm(lambda p, n: (200, {"instruction": "Go to the black fridge in the kitchen."}, 0, {}))
    inst = LLMInstructor(ChatClient(_config(tmp_path, server.url)), ctx)
    (out,) = inst.high_level(text, np.random.default_rng(0))
    assert (out.level, out.type, out.text, out.source) == ("high", "Attribute_Based",
                                                           "Go to the black fridge in the kitchen.", "llm:fake")


def test_malformed_json_is_asked_again_quoting_the_problem(fake_llm, tmp_path, scene):
    ctx, text = scene
    server = fake_llm(lambda p, n: (200, {"choices": [{"message": {"content": "Sure! The fridge."}}]}, 0, {}) if n == 1
                      else (200, {"instruction": "Find the black fridge and stop."}, 0, {}))
    inst = LLMInstructor(ChatClient(_config(tmp_path, server.url)), ctx)
    (out,) = inst.high_level(text, np.random.default_rng(0))
    assert out.source == "llm:fake" and out.text == "Find the black fridge and stop."
    assert len(server.prompts) == 2 and 'not JSON with an "instruction" string' in server.prompts[1]


def test_a_hallucinated_object_is_retried_then_replaced_by_the_template(fake_llm, tmp_path, scene):
    ctx, text = scene
    server = fake_llm(lambda p, n: (200, {"instruction": "Go to the piano next to the black fridge."}, 0, {}))
    inst = LLMInstructor(ChatClient(_config(tmp_path, server.url, answer_attempts=2)), ctx)
    (out,) = inst.high_level(text, np.random.default_rng(0))
    assert out.source == "template" and out.type == "Attribute_Based" and "black" in out.text and "fridge" in out.text
    assert len(server.prompts) == 2 and "there is no piano in this scene" in server.prompts[1]
    assert inst.stats["fallback"] == 1 and inst.stats["rejected"] == 2


def test_an_unreachable_server_falls_back_without_hammering(tmp_path, scene):
    ctx, text = scene
    probe = ThreadingHTTPServer(("127.0.0.1", 0), BaseHTTPRequestHandler)
    url = f"http://127.0.0.1:{probe.server_address[1]}/v1"
    probe.server_close()  # nothing listens there now: connection refused
    inst = LLMInstructor(ChatClient(_config(tmp_path, url, max_attempts=2)), ctx)
    outs = [inst.high_level(text, np.random.default_rng(s))[0] for s in range(5)]
    assert {o.source for o in outs} == {"template"}
    assert inst.stats["request failed"] == 3 and "after 2 attempts" in inst.summary()


# ---------------------------------------------------------------- gen-trajectories --instructions llm


def _files(root):
    return {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()}


def test_cli_llm_mode_writes_llm_rows_and_a_second_run_sends_no_request(fake_llm, run_cli, demo_built_run, tmp_path):
    from sagebench.episodes.shards import read_episodes

    server = fake_llm(lambda p, n: (200, goal_answer(p), 0, {}))
    run = tmp_path / "run"
    shutil.copytree(demo_built_run / "scenes", run / "scenes")
    args = ["gen-trajectories", run, "--per-scene", "8", "--instructions", "llm", "--llm-base-url", server.url,
            "--llm-model", "fake", "--llm-cache-dir", tmp_path / "cache", "--llm-concurrency", "2"]
    code, out, err = run_cli(*args)
    assert code == 0, err
    assert "8 trajectories, 24 episode rows" in out and "8 LLM answers used, 0 template fallbacks" in out
    episodes = run / "episodes" / "demo_apartment_0"
    rows = read_episodes(episodes).to_pylist()
    high = [r for r in rows if r["instruction_level"] == "high"]
    assert len(high) == 8 and {r["instruction_source"] for r in high} == {"llm:fake"}
    assert {r["instruction_source"] for r in rows if r["instruction_level"] == "low"} == {"template"}
    assert all(r["instruction_text"].startswith("Please go to the ") for r in high)
    first, sent = _files(episodes), len(server.prompts)
    assert sent == 8

    code, out, _ = run_cli(*args)
    assert code == 0 and len(server.prompts) == sent  # every answer came from the cache
    assert "0 requests, 8 from cache" in out
    assert _files(episodes) == first


def test_cli_llm_mode_needs_a_url_and_a_model(run_cli, demo_built_run, tmp_path):
    code, _, err = run_cli("gen-trajectories", demo_built_run, "--instructions", "llm", "--llm-model", "x")
    assert code == 2 and "error: --instructions llm needs --llm-base-url and --llm-model" in err
    code, _, err = run_cli("gen-trajectories", demo_built_run, "--instructions", "llm", "--llm-base-url", "http://127.0.0.1:9/v1",
                           "--llm-model", "x", "--llm-concurrency", "0")
    assert code == 2 and "error: --llm-concurrency: Input should be greater than or equal to 1" in err
    code, _, err = run_cli("gen-trajectories", demo_built_run, "--instructions", "llm", "--llm-base-url", "localhost:8000",
                           "--llm-model", "x")
    assert code == 2 and "error: --llm-base-url: must be an http(s) URL such as http://localhost:8000/v1" in err
