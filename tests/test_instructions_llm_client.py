"""The chat client against a fake server on 127.0.0.1 that misbehaves on purpose (tests/fake_llm.py).

Every failure mode ends within a stated bound (`bounded`, far above the expected time, guards hangs)
with an answer, an LLMError, or LLMUnavailable once the breaker is open. Timeouts are small here.
"""

from __future__ import annotations

import json
import threading
from datetime import datetime, timezone
from email.utils import format_datetime

import pytest
from fake_llm import Reply, answer, bounded, completion

from sagebench.http_client import MAX_RETRY_AFTER_S, retry_after_s
from sagebench.instructions.llm_client import (
    ANSWER_SCHEMA,
    STOP,
    ChatClient,
    LLMError,
    LLMUnavailable,
)
from sagebench.settings.gen_trajectories import LLMConfig

BOUND_S = 10.0  # every call below is expected to take well under a second or two


def config(tmp_path, url, **kw) -> LLMConfig:
    """A client of the fake server. Its deadline is far above a reply's time on a loaded machine, so a test that
    counts requests never counts a retry its timing caused; the tests of deadlines set their own short one."""
    return LLMConfig(**{"base_url": url, "model": "fake", "cache_dir": tmp_path / "cache", "backoff_s": 0.01,
                        "timeout_s": 5.0, **kw})


def test_a_good_answer_is_cached_under_every_generation_setting_but_not_the_url(fake_llm, tmp_path):
    server = fake_llm(lambda b, n: answer(f"echo {b['messages'][0]['content']}"))
    client = ChatClient(config(tmp_path, server.url))
    assert json.loads(client.complete("hello"))["instruction"] == "echo hello"
    assert json.loads(client.complete("hello"))["instruction"] == "echo hello"
    assert len(server.bodies) == 1 and client.stats["cache_hits"] == 1
    key = client.cache_path("hello")
    assert key != client.cache_path("hello!")
    for change in ({"model": "other"}, {"temperature": 0.7}, {"max_tokens": 64}, {"response_format": "none"}):
        other = ChatClient(config(tmp_path, server.url, **change))
        assert other.cache_path("hello") != key, change
    same = ChatClient(config(tmp_path, "http://elsewhere.invalid/v1", timeout_s=9, concurrency=2, max_attempts=1))
    assert same.cache_path("hello") == key  # the same model name on another server reuses the answer


def test_the_request_bounds_the_answer_and_asks_for_json_by_schema(fake_llm, tmp_path):
    server = fake_llm(lambda b, n: answer("ok"))
    ChatClient(config(tmp_path, server.url, max_tokens=77, temperature=0.5)).complete("x")
    (body,) = server.bodies
    assert body["max_tokens"] == 77 and body["stop"] == list(STOP) and body["temperature"] == 0.5
    assert body["response_format"] == {"type": "json_schema", "json_schema": {
        "name": "instruction", "strict": True, "schema": ANSWER_SCHEMA}}
    assert body["messages"] == [{"role": "user", "content": "x"}] and body["model"] == "fake"


@pytest.mark.parametrize("status", [400, 422, 500, 501])
def test_a_server_refusing_response_format_is_asked_again_without_it(fake_llm, tmp_path, status):
    """Any 4xx/5xx to a response_format (llama-cpp-python answers 500 to json_schema) means "not supported": the
    same prompt goes out the next way, and every later request is sent the way that worked."""
    server = fake_llm(lambda b, n: Reply(status, {"error": "response_format not supported"}) if "response_format" in b
                      else answer("plain"))
    client = ChatClient(config(tmp_path, server.url))
    assert json.loads(client.complete("a")) == {"instruction": "plain"}
    assert json.loads(client.complete("b")) == {"instruction": "plain"}
    assert [b.get("response_format", {}).get("type") for b in server.bodies] == ["json_schema", "json_object", None, None]
    assert [b["messages"][0]["content"] for b in server.bodies] == ["a", "a", "a", "b"]
    assert client.response_format == "none" and client.breaker.reason is None and client.stats["retries"] == 0


def test_json_object_is_used_when_only_the_schema_is_refused(fake_llm, tmp_path):
    server = fake_llm(lambda b, n: Reply(500, "grammar error") if b.get("response_format", {}).get("type") == "json_schema"
                      else answer("ok"))
    client = ChatClient(config(tmp_path, server.url))
    for prompt in "abc":
        client.complete(prompt)
    assert [b.get("response_format", {}).get("type") for b in server.bodies] == ["json_schema"] + ["json_object"] * 3
    assert client.response_format == "json_object"


@pytest.mark.parametrize("fmt, sent", [("json_schema", "json_schema"), ("json_object", "json_object"), ("none", None)])
def test_a_named_response_format_is_sent_as_is_and_its_refusal_is_an_error(fake_llm, tmp_path, fmt, sent):
    server = fake_llm(lambda b, n: Reply(400, "no") if b.get("response_format") else answer("ok"))
    client = ChatClient(config(tmp_path, server.url, response_format=fmt))
    if sent is None:
        client.complete("a")
    else:
        with pytest.raises(LLMError, match="HTTP 400 no"):
            client.complete("a")
    assert [b.get("response_format", {}).get("type") for b in server.bodies] == [sent]


def test_the_format_is_decided_once_before_other_threads_ask(fake_llm, tmp_path):
    """At concurrency 4 against a server refusing response_format, every request but the deciding one goes out
    the decided way: what is asked, and so what is answered, never depends on timing."""
    server = fake_llm(lambda b, n: Reply(500, "no") if "response_format" in b else answer(b["messages"][0]["content"]))
    client = ChatClient(config(tmp_path, server.url, concurrency=4))
    threads = [threading.Thread(target=client.complete, args=(f"p{k}",)) for k in range(12)]
    bounded(BOUND_S, lambda: [t.start() for t in threads] and [t.join() for t in threads])
    with_format = [b["messages"][0]["content"] for b in server.bodies if "response_format" in b]
    assert len(with_format) == 2 and len(set(with_format)) == 1 and len(server.bodies) == 14


def test_null_content_is_an_error_and_is_not_cached(fake_llm, tmp_path):
    server = fake_llm(lambda b, n: Reply(body=completion(None)))
    client = ChatClient(config(tmp_path, server.url))
    with pytest.raises(LLMError, match=r"the reply has no text \(content null; a reasoning or tool-call reply\?\)"):
        bounded(BOUND_S, client.complete, "x")
    assert len(server.bodies) == 1 and not client.cache_path("x").exists()


def test_a_cached_null_answer_is_asked_again(fake_llm, tmp_path):
    server = fake_llm(lambda b, n: answer("fresh"))
    client = ChatClient(config(tmp_path, server.url))
    path = client.cache_path("x")
    path.parent.mkdir(parents=True)
    path.write_text(json.dumps({"content": None}))  # written by an older sagebench
    assert json.loads(client.complete("x")) == {"instruction": "fresh"}
    assert len(server.bodies) == 1 and json.loads(path.read_text())["content"] == '{"instruction": "fresh"}'


@pytest.mark.parametrize("mode", ["not_http", "truncated"])
def test_a_non_http_or_truncated_reply_is_retried(fake_llm, tmp_path, mode):
    server = fake_llm(lambda b, n: Reply(body={"instruction": "bad"}, mode=mode) if n == 1 else answer("good"))
    client = ChatClient(config(tmp_path, server.url))
    assert json.loads(bounded(BOUND_S, client.complete, "x")) == {"instruction": "good"}
    assert len(server.bodies) == 2 and client.stats["retries"] == 1


@pytest.mark.parametrize("mode", ["drip", "hang"])
def test_a_dripping_or_hanging_server_is_cut_at_the_whole_request_deadline(fake_llm, tmp_path, mode):
    server = fake_llm(lambda b, n: Reply(body={"instruction": "x" * 40}, mode=mode, drip_s=0.05))
    client = ChatClient(config(tmp_path, server.url, timeout_s=0.4, max_attempts=2))
    with pytest.raises(LLMError, match=r"no complete reply within 0.4 s \(after 2 attempts\)"):
        bounded(BOUND_S, client.complete, "x")
    assert len(server.bodies) == 2
    # each socket read came within the per-read timeout; only the whole-request deadline stops the drip
    assert server.dripped < 2 * 0.4 / 0.05 + 4


def test_a_reply_nested_too_deep_is_an_error_not_a_crash(fake_llm, tmp_path):
    server = fake_llm(lambda b, n: Reply(body="[" * 100_000 + "]" * 100_000))
    with pytest.raises(LLMError, match=r": the reply's JSON is nested deeper than 64 levels$"):
        bounded(BOUND_S, ChatClient(config(tmp_path, server.url, response_format="none")).complete, "x")
    assert len(server.bodies) == 1


def test_404_is_not_retried(fake_llm, tmp_path):
    server = fake_llm(lambda b, n: Reply(404, {"error": "model 'fake' not found"}))
    with pytest.raises(LLMError, match="HTTP 404 .*model 'fake' not found"):
        bounded(BOUND_S, ChatClient(config(tmp_path, server.url, response_format="none")).complete, "x")
    assert len(server.bodies) == 1


def test_retry_after_takes_seconds_or_an_http_date():
    now = datetime(2026, 11, 24, 9, 0, 0, tzinfo=timezone.utc)
    assert retry_after_s("2", now) == 2.0
    assert retry_after_s("Tue, 24 Nov 2026 09:00:03 GMT", now) == 3.0
    assert retry_after_s("Tue, 24 Nov 2026 08:59:00 GMT", now) == 0.0  # in the past
    assert retry_after_s("Wed, 25 Nov 2026 09:00:00 GMT", now) == MAX_RETRY_AFTER_S
    assert retry_after_s("soon", now) == retry_after_s(None, now) == retry_after_s("-5", now) == 0.0


def test_429_with_an_http_date_is_retried_after_that_date(fake_llm, tmp_path):
    def respond(b, n):
        if n == 1:
            when = format_datetime(datetime.now(timezone.utc), usegmt=True)  # now: retry at once
            return Reply(429, {"error": "slow down"}, {"Retry-After": when})
        return answer("ok")

    server = fake_llm(respond)
    client = ChatClient(config(tmp_path, server.url, breaker_failures=1))
    assert json.loads(bounded(BOUND_S, client.complete, "x")) == {"instruction": "ok"}
    assert len(server.bodies) == 2 and client.breaker.reason is None  # a rate limit is no failure


def test_5xx_until_the_attempts_run_out_raises_and_caches_nothing(fake_llm, tmp_path):
    server = fake_llm(lambda b, n: Reply(503, {"error": "down"}))
    client = ChatClient(config(tmp_path, server.url, max_attempts=3, response_format="none"))
    with pytest.raises(LLMError, match=r"HTTP 503 .* \(after 3 attempts\)"):
        bounded(BOUND_S, client.complete, "x")
    assert len(server.bodies) == 3 and not client.cache_path("x").exists()


def test_the_breaker_stops_all_threads_after_n_consecutive_failures(fake_llm, tmp_path):
    server = fake_llm(lambda b, n: Reply(503, {"error": "down"}))
    client = ChatClient(config(tmp_path, server.url, concurrency=4, breaker_failures=3, max_attempts=3,
                               response_format="none"))
    errors: list[Exception] = []

    def ask(k):
        try:
            client.complete(f"prompt {k}")
        except LLMError as err:
            errors.append(err)

    threads = [threading.Thread(target=ask, args=(k,)) for k in range(16)]
    bounded(BOUND_S, lambda: [t.start() for t in threads] and [t.join() for t in threads])
    assert len(errors) == 16
    assert len(server.bodies) <= 3 + 4 - 1  # the failures that opened it, plus the attempts already in flight
    assert client.breaker.reason.startswith("stopped asking after 3 consecutive failed requests (last: HTTP 503")
    sent = len(server.bodies)
    with pytest.raises(LLMUnavailable):
        client.complete("later")
    assert len(server.bodies) == sent


def test_a_success_resets_the_breaker(fake_llm, tmp_path):
    server = fake_llm(lambda b, n: answer("ok") if n % 2 == 0 else Reply(404, {"error": "odd"}))
    client = ChatClient(config(tmp_path, server.url, breaker_failures=2, max_attempts=1, response_format="none"))
    for k in range(6):
        try:
            client.complete(f"p{k}")
        except LLMError:
            pass
    assert client.breaker.reason is None and len(server.bodies) == 6


def test_at_most_concurrency_requests_are_in_flight(fake_llm, tmp_path):
    together = threading.Barrier(4, timeout=5)  # replies go out 4 at a time: a 5th in flight would show

    def respond(body, n):
        together.wait()
        return answer("ok")

    server = fake_llm(respond)
    client = ChatClient(config(tmp_path, server.url, concurrency=4, timeout_s=8, response_format="none"))
    threads = [threading.Thread(target=client.complete, args=(f"p{k}",)) for k in range(8)]
    bounded(BOUND_S, lambda: [t.start() for t in threads] and [t.join() for t in threads])
    assert len(server.bodies) == 8 and server.most_in_flight == 4 and not together.broken


def test_cancel_cuts_a_request_in_flight(fake_llm, tmp_path):
    server = fake_llm(lambda b, n: Reply(mode="hang"))
    client = ChatClient(config(tmp_path, server.url, timeout_s=60))
    result: list[BaseException] = []
    t = threading.Thread(target=lambda: result.append(pytest.raises(LLMUnavailable, client.complete, "x").value))
    t.start()
    while not server.bodies:
        threading.Event().wait(0.01)
    client.cancel()
    bounded(BOUND_S, t.join)
    assert isinstance(result[0], LLMUnavailable) and len(server.bodies) == 1


def test_only_the_given_key_is_sent_as_the_bearer_token(fake_llm, tmp_path):
    server = fake_llm(lambda b, n: answer("ok"))
    ChatClient(config(tmp_path, server.url), api_key="sekrit").complete("a")
    ChatClient(config(tmp_path, server.url)).complete("b")
    assert server.headers[0]["Authorization"] == "Bearer sekrit" and "Authorization" not in server.headers[1]
    with pytest.raises(ValueError, match="api_key_env"):
        LLMConfig(api_key_env="AWS_SECRET_ACCESS_KEY")  # a config cannot pick the variable


def test_a_prose_answer_is_not_cached_and_refresh_asks_again(fake_llm, tmp_path):
    replies = iter(["Go to the sofa.", '{"instruction": "Go to the sofa."}', '{"instruction": "Go to the bed."}'])
    server = fake_llm(lambda b, n: Reply(body=completion(next(replies))))
    client = ChatClient(config(tmp_path, server.url))
    keep = lambda answer: answer.startswith("{")  # noqa: E731 - what the instructor keeps: JSON answers
    assert client.complete("p", keep=keep) == "Go to the sofa." and not client.cache_path("p").exists()
    assert client.complete("p", keep=keep) == '{"instruction": "Go to the sofa."}'  # asked again, then cached
    assert client.complete("p", keep=keep) == '{"instruction": "Go to the sofa."}' and len(server.bodies) == 2
    fresh = ChatClient(config(tmp_path, server.url, refresh=True))
    assert fresh.complete("p", keep=keep) == '{"instruction": "Go to the bed."}' and len(server.bodies) == 3
    assert client.complete("p") == '{"instruction": "Go to the bed."}'  # the refreshed answer replaced the old


@pytest.mark.parametrize("props, configured, url, want", [
    (None, None, None, 1),  # a server on this machine that reports nothing: one request at a time
    ({"total_slots": 3}, None, None, 3),  # a llama.cpp server's slots
    ({"total_slots": 3}, 2, None, 2),  # the configured number wins
    (None, None, "http://sagebench-test.invalid/v1", 4),  # elsewhere, nothing reported
])
def test_concurrency_defaults_to_the_servers_slots_or_one_locally(fake_llm, tmp_path, props, configured, url, want):
    server = fake_llm(lambda b, n: answer("ok"), props=props)
    client = ChatClient(config(tmp_path, url or server.url, concurrency=configured, timeout_s=2))
    assert bounded(BOUND_S, client.discover_concurrency) == want == client.concurrency


def test_a_one_at_a_time_local_server_is_not_asked_past_its_deadline(fake_llm, tmp_path):
    """The deadline counts from when a request is sent, and a local server is sent one at a time: a server that
    takes 0.3 s per request, one after another, answers all 6 within a 0.5 s deadline."""
    busy = threading.Lock()

    def respond(body, n):
        with busy:
            threading.Event().wait(0.3)
            return answer("ok")

    server = fake_llm(respond)
    client = ChatClient(config(tmp_path, server.url, timeout_s=0.5, max_attempts=1))
    assert client.discover_concurrency() == 1
    threads = [threading.Thread(target=client.complete, args=(f"p{k}",)) for k in range(6)]
    bounded(BOUND_S, lambda: [t.start() for t in threads] and [t.join() for t in threads])
    # 4 at once (the old default) would leave the 4th queued 0.9 s at the server, past its deadline
    assert len(server.bodies) == 6 and all(client.cache_path(f"p{k}").exists() for k in range(6))
