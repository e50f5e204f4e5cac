"""LLM mode: the prompt, the instructor (grounding, retry, fallback, breaker) and gen-trajectories
--instructions llm, against the fake server of tests/fake_llm.py on 127.0.0.1 (no other network is used).
"""

import json
import os
import re
import shutil
import signal
import subprocess
import sys
import threading
import time
import zlib

import numpy as np
import pytest
from fake_llm import FakeLLM, Reply, answer, bounded, completion
from signals import as_from_a_terminal

from sagebench.instructions.base import TrajectoryText, make_context
from sagebench.instructions.high_level import scenario_data
from sagebench.instructions.llm import LLMInstructor
from sagebench.instructions.llm_client import ChatClient
from sagebench.instructions.naming import ObjectInfo, RoomInfo
from sagebench.instructions.prompt import build_prompt, estimate_tokens, parse_answer
from sagebench.settings.gen_trajectories import LLMConfig

BOUND_S = 20.0  # far above what any call here takes


def goal_answer(prompt: str) -> Reply:
    """A grounded answer of the type the prompt asks for, naming the goal as the prompt gives it: a need it serves
    (Scenario_Driven, from scenarios.toml by the goal's category or room type in the map), something carried there
    (Add_Object), its room (Area_Based), a relation the prompt's goal facts give (Relative_Relationship; the room
    with an object of it for a room goal) or its attributes as the map lists them (Attribute_Based)."""
    kind = re.search(r"^Write ONE instruction of type (.+?)\. ", prompt, re.M).group(1)
    goal, room = re.search(r"^- goal: (.*?)(?:, in (.*))?$", prompt, re.M).groups()
    facts = [f for f in re.search(r"^Facts about the goal: (.*)$", prompt, re.M).group(1).split("; ")
             if f != "none" and not f.startswith("within its room")]
    go = f"Please go to {goal} and wait there."
    if kind == "Scenario Driven":
        kind_of = re.search(rf"^- {re.escape(goal)}(?:: | \(type: )([a-z ]+)", prompt, re.M).group(1).replace(" ", "_")
        needs, _ = scenario_data()
        say = next((n.say[0] + " " for n in needs if kind_of in n.categories or kind_of in n.rooms), "")
        return answer(say + go)
    if kind == "Add Object":
        return answer(f"Take it to {goal} and leave it there.")
    if kind == "Area Based":
        return answer(f"Go into {room} and stop at {goal}." if room else go)
    if kind == "Relative Relationship":
        if facts:
            return answer(f"Please go to {facts[0]} and wait there.")
        inside = re.search(rf"^- ([^:]+): [^;]+; [^;]+; in {re.escape(goal)}\b", prompt, re.M)
        return answer(f"Go to the room with {inside.group(1)}." if inside else go)
    line = re.search(rf"^- {re.escape(goal)}: ([a-z ]+); ([^;]+);", prompt, re.M)
    adjectives = " ".join(v.split(" ", 1)[1] for v in line.group(2).split(", ") if " " in v) if line else ""
    return answer(f"Please go to the {adjectives} {line.group(1)}{' in ' + room if room else ''} and wait there."
                  if line and adjectives else go)


def _config(tmp_path, url, **kw):
    return LLMConfig(base_url=url, model="fake", cache_dir=tmp_path / "cache", backoff_s=0.01, **kw)


def test_parse_answer_tolerates_fences_and_the_stop_brace_and_rejects_non_json():
    assert parse_answer('```json\n{"instruction": "Go to  the sofa."}\n```') == "Go to the sofa."
    assert parse_answer('{"instruction": "Go to the sofa."') == "Go to the sofa."  # cut at the stop "}"
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


def test_a_prompt_over_its_budget_leaves_out_the_farthest_objects_first(fake_llm, tmp_path, scene):
    ctx0, text0 = scene
    extra = [ObjectInfo(4, "armchair", "l", {"colour": "green"}), ObjectInfo(5, "plant", "k", {"colour": "green"})]
    boxes = {1: (1, 1, 3, 2), 2: (8, 3, 8.7, 3.8), 3: (6, 1, 7, 2), 4: (0.2, 0.2, 0.6, 0.6), 5: (8.5, 0.1, 8.9, 0.5)}
    feet = {i: [np.array([(a, b), (c, b), (c, d), (a, d)], float)] for i, (a, b, c, d) in boxes.items()}
    ctx = make_context([*ctx0.objects, *extra], ctx0.rooms, ctx0.room_polygons, feet, type_mix=ctx0.type_mix)
    text = TrajectoryText(text0.waypoints, "the sofa", "the fridge", "object", "object", 1, 2, "l", "k", ctx)
    full = build_prompt("Attribute_Based", text)
    assert build_prompt("Attribute_Based", text, estimate_tokens(full)) == full
    short = build_prompt("Attribute_Based", text, estimate_tokens(full) - 1)  # the plant is 2.7 m off, the armchair 2.4
    assert estimate_tokens(short) < estimate_tokens(full) and "(1 more objects, farther from the path, are left out)" in short
    assert "- the plant: plant" not in short and "- the armchair: armchair" in short
    shortest = build_prompt("Attribute_Based", text, estimate_tokens(full) - 25)
    assert "- the armchair" not in shortest and "(2 more objects" in shortest and "- the fridge: fridge" in shortest
    assert "- the sofa: sofa" in shortest and "- the dining table: dining table" in shortest  # start, passed

    server = fake_llm(lambda b, n: answer("unused"))  # over budget even without them: the template, no request
    inst = LLMInstructor(ChatClient(_config(tmp_path, server.url, prompt_tokens=500)), ctx)
    assert estimate_tokens(shortest) > 500
    (out,) = inst.high_level(text, np.random.default_rng(0))
    assert out.source == "template" and server.bodies == [] and inst.stats["over budget"] == 1
    assert "1 prompts over the budget of 500 tokens" in inst.summary()


def test_a_grounded_answer_is_used_with_the_model_as_source(fake_llm, tmp_path, scene):
    ctx, text = scene
    server = fake_llm(lambda b, n: answer("Go to the black fridge in the kitchen."))
    inst = LLMInstructor(ChatClient(_config(tmp_path, server.url)), ctx)
    (out,) = inst.high_level(text, np.random.default_rng(0))
    assert (out.level, out.type, out.text, out.source) == ("high", "Attribute_Based",
                                                           "Go to the black fridge in the kitchen.", "llm:fake")


def test_malformed_json_is_asked_again_quoting_the_problem(fake_llm, tmp_path, scene):
    ctx, text = scene
    server = fake_llm(lambda b, n: Reply(body={"choices": [{"message": {"content": "Sure! The fridge."}}]}) if n == 1
                      else answer("Find the black fridge and stop."))
    inst = LLMInstructor(ChatClient(_config(tmp_path, server.url)), ctx)
    (out,) = inst.high_level(text, np.random.default_rng(0))
    assert out.source == "llm:fake" and out.text == "Find the black fridge and stop."
    assert len(server.prompts) == 2 and 'not JSON with an "instruction" string' in server.prompts[1]


def test_a_hallucinated_object_is_retried_then_replaced_by_the_template(fake_llm, tmp_path, scene):
    ctx, text = scene
    server = fake_llm(lambda b, n: answer("Go to the piano next to the black fridge."))
    inst = LLMInstructor(ChatClient(_config(tmp_path, server.url, answer_attempts=2)), ctx)
    (out,) = inst.high_level(text, np.random.default_rng(0))
    assert out.source == "template" and out.type == "Attribute_Based" and "black" in out.text and "fridge" in out.text
    assert len(server.prompts) == 2 and "there is no piano in this scene" in server.prompts[1]
    assert inst.stats["fallback"] == 1 and inst.stats["rejected"] == 2


def test_an_unreachable_server_falls_back_without_hammering(tmp_path, scene):
    ctx, text = scene
    server = FakeLLM(lambda b, n: answer("unused"))
    server.close()  # nothing listens there now: connection refused
    inst = LLMInstructor(ChatClient(_config(tmp_path, server.url, max_attempts=2, breaker_failures=3)), ctx)
    outs = [bounded(BOUND_S, inst.high_level, text, np.random.default_rng(s))[0] for s in range(5)]
    assert {o.source for o in outs} == {"template"}
    assert inst.stats["request failed"] == 1 and inst.stats["not asked"] == 4  # 2 + 1 attempts opened the breaker
    assert "stopped asking after 3 consecutive failed requests (last: URLError" in inst.summary()
    assert not inst.share().enough and inst.share().line() == "0 of 5 high-level rows from the model (0 %), 5 template"


def test_a_server_dying_mid_run_stops_the_asking_at_once(fake_llm, tmp_path, scene):
    ctx, text = scene
    server = fake_llm(lambda b, n: answer("Go to the black fridge in the kitchen."))
    inst = LLMInstructor(ChatClient(_config(tmp_path, server.url, breaker_failures=2, max_attempts=2)), ctx)
    first = [inst.high_level(text, np.random.default_rng(s))[0] for s in range(2)]  # same prompt: one request
    server.close()
    inst.client.cache_dir = tmp_path / "empty-cache"  # make every later trajectory ask
    later = [bounded(BOUND_S, inst.high_level, text, np.random.default_rng(s))[0] for s in range(6)]
    assert [o.source for o in first] == ["llm:fake"] * 2 and {o.source for o in later} == {"template"}
    assert inst.stats["request failed"] == 1 and inst.stats["not asked"] == 5
    assert inst.share().line() == "2 of 8 high-level rows from the model (25 %), 6 template"


# ---------------------------------------------------------------- gen-trajectories --instructions llm


def _files(root):
    return {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()}


@pytest.fixture
def run(demo_built_run, tmp_path):
    out = tmp_path / "run"
    shutil.copytree(demo_built_run / "scenes", out / "scenes")
    return out


def _llm_args(run, url, tmp_path, *more):
    return ["gen-trajectories", run, "--per-scene", "8", "--instructions", "llm", "--llm-base-url", url,
            "--llm-model", "fake", "--llm-cache-dir", tmp_path / "cache", *more]


def test_cli_llm_mode_writes_llm_rows_and_a_second_run_sends_no_request(fake_llm, run_cli, run, tmp_path):
    from sagebench.episodes.shards import read_episodes

    server = fake_llm(lambda b, n: goal_answer(b["messages"][0]["content"]))
    args = _llm_args(run, server.url, tmp_path, "--llm-concurrency", "4")
    code, out, err = run_cli(*args)
    assert code == 0, err
    assert "8 trajectories, 24 episode rows" in out and "8 of 8 high-level rows from the model (100 %), 0 template" in out
    episodes = run / "episodes" / "demo_apartment_0"
    rows = read_episodes(episodes).to_pylist()
    high = [r for r in rows if r["instruction_level"] == "high"]
    assert len(high) == 8 and {r["instruction_source"] for r in high} == {"llm:fake"}
    assert {r["instruction_source"] for r in rows if r["instruction_level"] == "low"} == {"template"}
    assert {r["instruction_text"] for r in high} <= {goal_answer(p).body["instruction"] for p in server.prompts}
    first, sent = _files(episodes), len(server.prompts)
    assert sent == 8 and server.most_in_flight <= 4

    code, out, _ = run_cli(*args)
    assert code == 0 and len(server.prompts) == sent  # every answer came from the cache
    assert "0 requests, 8 from cache" in out
    assert _files(episodes) == first


@pytest.mark.parametrize("reply", [Reply(404, {"error": "model not found"}), Reply(200, "<html>not json</html>"),
                                   Reply(body=completion(None)), Reply(mode="hang"), Reply(mode="not_http")],
                         ids=["404", "non-JSON", "content null", "hang", "non-HTTP"])
def test_cli_exits_1_and_writes_nothing_when_no_answer_comes(fake_llm, run_cli, run, tmp_path, reply):
    server = fake_llm(lambda b, n: reply)
    code, out, err = bounded(BOUND_S, run_cli, "-q", *_llm_args(run, server.url, tmp_path, "--llm-timeout", "0.5"))
    assert code == 1 and not (run / "episodes").exists()
    (line,) = err.strip().splitlines()  # -q: no progress line (printed every 5 s off a terminal) beside the error
    assert line.startswith(f"error: {run / 'scenes' / 'demo_apartment_0'}: --instructions llm: no high-level row "
                           "came from the model (0 of 8 high-level rows from the model (0 %), 8 template;")
    assert "stopped asking after 6 consecutive failed requests" in line and len(server.bodies) <= 6 + 4 - 1


def test_a_server_dying_mid_run_keeps_the_answers_and_warns_once(fake_llm, run, tmp_path, capsys):
    from sagebench.episodes.shards import read_episodes
    from sagebench.settings.gen_trajectories import GenTrajectoriesConfig, LLMConfig
    from sagebench.stages.gen_trajectories import gen_trajectories

    def respond(body, n):
        if n <= 3:
            return goal_answer(body["messages"][0]["content"])
        threading.Thread(target=server.close).start()  # from now on: connection refused
        return Reply(mode="not_http")

    server = fake_llm(respond)
    config = GenTrajectoriesConfig(per_scene=8, instructions="llm", llm=LLMConfig(
        base_url=server.url, model="fake", cache_dir=tmp_path / "cache", concurrency=1, backoff_s=0.01, min_share=0))
    (result,) = bounded(BOUND_S, gen_trajectories, run, config)
    assert "3 of 8 high-level rows from the model (38 %), 5 template" in result.summary()
    assert capsys.readouterr().err.count("stopped asking after 6 consecutive failed requests") == 1
    high = [r for r in read_episodes(run / "episodes" / "demo_apartment_0").to_pylist() if r["instruction_level"] == "high"]
    assert sum(r["instruction_source"] == "llm:fake" for r in high) == 3


def test_cli_min_share_fails_a_run_with_too_few_llm_rows(fake_llm, run_cli, run, tmp_path):
    def respond(body, n):  # a good answer for about half the trajectories (by a hash of the prompt), else none
        prompt = body["messages"][0]["content"]
        good = "Your previous answer" not in prompt and zlib.crc32(prompt.encode()) % 2 == 0
        return goal_answer(prompt) if good else answer("Go to it.")

    server = fake_llm(respond)
    code, _, err = run_cli(*_llm_args(run, server.url, tmp_path, "--llm-min-share", "0.99"))
    assert code == 1 and "fewer high-level rows from the model than --llm-min-share 0.99" in err
    assert re.search(r"\b[1-7] of 8 high-level rows from the model", err)
    assert not (run / "episodes").exists()


def test_cli_llm_options_need_llm_mode_a_url_and_a_model_and_a_writable_cache(run_cli, run, tmp_path):
    def fails(*args):
        code, out, err = run_cli("gen-trajectories", run, *args)
        assert code == 2 and out == "" and not (run / "episodes").exists()
        return err.strip()

    assert fails("--instructions", "llm", "--llm-model", "x") == \
        "error: --instructions llm needs --llm-base-url and --llm-model"
    url = ["--instructions", "llm", "--llm-base-url", "http://127.0.0.1:9/v1", "--llm-model", "x"]
    assert fails(*url, "--llm-concurrency", "0") == "error: --llm-concurrency: Input should be greater than or equal to 1"
    assert fails(*url, "--llm-timeout", "0") == "error: --llm-timeout: Input should be greater than 0"
    assert fails(*url, "--llm-min-share", "1.5") == "error: --llm-min-share: Input should be less than or equal to 1"
    assert fails("--instructions", "llm", "--llm-base-url", "localhost:8000", "--llm-model", "x") == \
        "error: --llm-base-url: must be an http(s) URL such as http://localhost:8000/v1, got 'localhost:8000'"
    assert fails("--llm-model", "x") == "error: --llm-model: used only with --instructions llm"
    assert fails("--instructions", "template", "--llm-concurrency", "4") == \
        "error: --llm-concurrency: used only with --instructions llm"  # even at its default
    assert fails("--llm-api-key-env", "HOME") == "error: --llm-api-key-env: used only with --instructions llm"
    assert fails(*url, "--llm-api-key-env", "SAGEBENCH_NO_SUCH_VARIABLE") == \
        "error: --llm-api-key-env: the environment variable SAGEBENCH_NO_SUCH_VARIABLE is not set"
    blocker = tmp_path / "a-file"
    blocker.write_text("")
    assert fails(*url, "--llm-cache-dir", blocker / "cache") == \
        f"error: {blocker / 'cache'}: --llm-cache-dir: cannot write the answer cache: Not a directory"


def test_ctrl_c_stops_promptly_and_writes_nothing(fake_llm, run, tmp_path):
    server = fake_llm(lambda b, n: Reply(mode="hang"))
    proc = subprocess.Popen([sys.executable, "-m", "sagebench", *map(str, _llm_args(run, server.url, tmp_path,
                             "--llm-timeout", "60", "--llm-concurrency", "4", "--llm-response-format", "none"))], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env={**os.environ, "PYTHONUNBUFFERED": "1"}, preexec_fn=as_from_a_terminal)
    try:
        bounded(BOUND_S * 3, lambda: [time.sleep(0.05) for _ in iter(lambda: len(server.bodies) >= 4, True)])
        proc.send_signal(signal.SIGINT)
        _, err = bounded(BOUND_S, proc.communicate)
    finally:
        proc.kill()
    assert proc.returncode == 130 and err.strip().splitlines()[-1] == \
        "error: interrupted: the scene in progress was not written"
    assert len(server.bodies) == 4 and not (run / "episodes").exists()


def test_run_config_sets_the_llm_settings_but_not_the_key_variable(tmp_path):
    from sagebench.errors import ConfigError
    from sagebench.pipeline.config import load_run_config

    path = tmp_path / "run.toml"
    base = 'scenes = ["s"]\nout = "o"\n[gen_trajectories]\ninstructions = "llm"\n[gen_trajectories.llm]\n' \
           'base_url = "http://127.0.0.1:8000/v1"\nmodel = "m"\n'
    path.write_text(base + "timeout_s = 5\nmax_attempts = 2\ntemperature = 0.3\nmax_tokens = 64\nconcurrency = 2\n")
    llm = load_run_config(path).gen_trajectories.llm
    assert (llm.timeout_s, llm.max_attempts, llm.temperature, llm.max_tokens, llm.concurrency) == (5, 2, 0.3, 64, 2)
    path.write_text(base + 'api_key_env = "AWS_SECRET_ACCESS_KEY"\n')
    with pytest.raises(ConfigError) as err:
        load_run_config(path)
    assert str(err.value) == f"{path}: gen_trajectories.llm.api_key_env: Extra inputs are not permitted"
    path.write_text(base.replace('instructions = "llm"', 'instructions = "template"'))
    with pytest.raises(ConfigError, match=r"the llm table\) are used only with --instructions llm"):
        load_run_config(path)


def test_two_runs_at_concurrency_4_against_a_server_refusing_response_format_are_byte_identical(
        fake_llm, run_cli, demo_built_run, tmp_path):
    """llama-cpp-python answers 500 to a json_schema response_format: the first request decides, once, that the
    server takes none, so no trajectory's answer depends on which request happened to be in flight."""
    server = fake_llm(lambda b, n: Reply(500, "grammar error") if "response_format" in b
                      else goal_answer(b["messages"][0]["content"]))
    shards = []
    for k in range(2):
        out = tmp_path / f"run{k}"
        shutil.copytree(demo_built_run / "scenes", out / "scenes")
        code, stdout, err = run_cli(*_llm_args(out, server.url, tmp_path / f"c{k}", "--llm-concurrency", "4"))
        assert code == 0, err
        assert "8 of 8 high-level rows from the model (100 %)" in stdout
        shards.append(_files(out / "episodes"))
    assert shards[0] == shards[1]
    assert sum("response_format" in b for b in server.bodies) == 2 * 2  # json_schema, json_object: once per run


def test_the_default_minimum_share_fails_a_mostly_template_scene_and_says_how_to_keep_it(fake_llm, run_cli, run,
                                                                                          tmp_path):
    def respond(body, n):  # answers that name a wrong goal for all but about a third of the trajectories
        prompt = body["messages"][0]["content"]
        good = "Your previous answer" not in prompt and zlib.crc32(prompt.encode()) % 3 == 0
        return goal_answer(prompt) if good else answer("Go to the kitchen and wait there.")

    server = fake_llm(respond)
    code, _, err = run_cli(*_llm_args(run, server.url, tmp_path))
    (line,) = err.splitlines()
    assert code == 1 and "fewer high-level rows from the model than --llm-min-share 0.5" in line
    assert line.endswith("nothing written (--llm-min-share 0 keeps the template rows instead)")
    grouped = re.search(r"(\d+) answers rejected by the grounding check \(((?:\d+ [a-z ]+(?:, )?)+)\)", line)
    counts = dict((why, int(n)) for n, why in re.findall(r"(\d+) ([a-z ]+)", grouped.group(2)))
    assert sum(counts.values()) == int(grouped.group(1)) and "wrong goal" in counts, line  # grouped by reason
    assert not (run / "episodes").exists()


# ---------------------------------------------------------------- nogoal's instruction in llm mode

PHRASINGS = ["Explore this home as widely as you can without bumping into anything.",
             "Look around every part of the place, and avoid hitting furniture or walls.",
             "Wander through as much of the house as possible while never colliding with objects.",
             "Survey the whole environment carefully, avoiding collisions with walls and things."]


def _phrasing(body: dict, n: int) -> Reply:
    """The next of PHRASINGS (those the prompt quotes are written), but a first answer for the first and third
    that the checks refuse: one that is no exploring, one that repeats the first."""
    prompt = body["messages"][0]["content"]
    k = sum(p in prompt.split("Your previous answer was:")[0] for p in PHRASINGS)
    if "was rejected because" not in prompt and k in (0, 2):
        return answer("Go to the kitchen and wait there." if k == 0 else PHRASINGS[0])
    return answer(PHRASINGS[k])


def test_llm_mode_phrases_each_nogoal_instruction_its_own_way(fake_llm, run_cli, run, tmp_path):
    """Each nogoal episode of a scene gets its own wording of SAGE's exploration instruction, checked (it still says
    explore and avoid collisions, repeats none before it) and asked again when it does not; template mode and a
    model whose answers never pass keep SAGE's sentence."""
    from sagebench.episodes.shards import read_episodes
    from sagebench.episodes.tasks import NOGOAL_INSTRUCTION

    server = fake_llm(_phrasing)
    args = ["gen-trajectories", run, "--tasks", "nogoal", "--task-episodes", "4", "--instructions", "llm",
            "--llm-base-url", server.url, "--llm-model", "fake", "--llm-cache-dir", tmp_path / "cache"]
    code, out, err = run_cli(*args)
    assert code == 0, err
    assert "nogoal: 4 of 4 instructions phrased by the model, 0 SAGE-Bench's sentence" in out
    rows = read_episodes(run / "episodes" / "demo_apartment_0").to_pylist()
    assert [(r["instruction_text"], r["instruction_source"]) for r in rows] == [(p, "llm:fake") for p in PHRASINGS]
    retried = [p for p in server.prompts if "was rejected because" in p]
    assert len(retried) == 2 and "it does not tell the robot to explore" in retried[0]
    assert "it repeats a phrasing already written" in retried[1]
    sent, first = len(server.prompts), _files(run / "episodes")
    assert run_cli(*args)[0] == 0 and len(server.prompts) == sent and _files(run / "episodes") == first  # cached

    never = fake_llm(lambda b, n: answer("Go to the kitchen and wait there."))
    other = ["--llm-base-url", never.url, "--llm-model", "fake", "--llm-cache-dir", tmp_path / "other"]
    for more in ([*args[6:8], *other], []):  # a model whose answers never pass; then template mode
        code, out, err = run_cli(*args[:6], *more)
        assert code == 0, err
        rows = read_episodes(run / "episodes" / "demo_apartment_0").to_pylist()
        assert [(r["instruction_text"], r["instruction_source"]) for r in rows] == [(NOGOAL_INSTRUCTION, "template")] * 4
        assert ("nogoal: 0 of 4 instructions phrased by the model, 4 SAGE-Bench's sentence" in out) == bool(more)
