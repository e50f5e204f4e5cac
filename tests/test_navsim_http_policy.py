"""The HTTP transport against local policy servers that drip, hang, fail or close connections: one deadline per
request, retries for connection errors only, a failed request fails its slot alone, opaque episode ids.

The two deadline tests bound a request's wall time by its timeout plus 5 s (the rollout's promise to the user);
they measure a hang being cut, not the machine's speed: the dripped reply outlasts the deadline by a minute, a byte
every 0.2 s (so no per-read timeout fires), and a client whose watchdog missed the socket took that minute."""

from __future__ import annotations

import json
import time
import types

import numpy as np
import pytest

from fake_policy import FakePolicy
from sagebench.episodes.episode import Episode
from sagebench.navsim.actions import Action
from sagebench.navsim.http_policy import HttpPolicy, RequestFailed, post
from sagebench.navsim.policies import PolicyFailure
from sagebench.navsim.protocol import encode_request, request_fields

OBS = {"depth": np.full((4, 4), 2.0, np.float32), "instruction": "go on"}


def body(step: int = 0) -> tuple[str, bytes]:
    return encode_request(OBS, request_fields(OBS, episode_id="e", step=step, action_space="discrete",
                                              profile="custom"))


@pytest.fixture
def server():
    made: list[FakePolicy] = []

    def start(*args, **kwargs) -> FakePolicy:
        made.append(FakePolicy(*args, **kwargs))
        return made[-1]

    yield start
    for s in made:
        s.close()


@pytest.mark.parametrize("fault", ["drip", "hang"])
def test_a_slow_or_hung_server_is_cut_at_the_deadline(server, fault):
    s = server(fault)
    content_type, data = body()
    start = time.monotonic()
    with pytest.raises(RequestFailed, match=r"^no reply within 1 s$"):
        post(s.url, data, content_type, timeout=1.0)
    assert time.monotonic() - start < 1.0 + 5.0
    assert s.requests == 1  # a timeout is not retried


def test_a_closed_connection_is_retried_and_then_answered(server):
    s = server("close", faulty=lambda n: n <= 2)
    content_type, data = body()
    assert json.loads(post(s.url, data, content_type, timeout=30.0, retries=3)) == {"action": "MOVE_FORWARD"}
    assert s.requests == 3


def test_connections_that_keep_closing_fail_after_the_retries(server):
    s = server("close")
    content_type, data = body()
    with pytest.raises(RequestFailed, match="^connection error: RemoteDisconnected"):
        post(s.url, data, content_type, timeout=30.0, retries=2)
    assert s.requests == 3


def test_a_reply_cut_short_is_not_sent_again(server):
    """The policy answered (its step is taken: a recurrent policy's state moved on), so sending the step again
    would show it the same observation twice; only a connection closed before any reply is retried."""
    s = server("truncated")
    content_type, data = body()
    with pytest.raises(RequestFailed, match="^connection error: IncompleteRead"):
        post(s.url, data, content_type, timeout=30.0, retries=3)
    assert s.requests == 1 and len(s.seen) == 1


def test_an_http_error_is_not_retried(server):
    s = server("status500")
    content_type, data = body()
    with pytest.raises(RequestFailed, match="^HTTP 500 policy crashed$"):
        post(s.url, data, content_type, timeout=30.0, retries=3)
    assert s.requests == 1


def test_a_retry_never_waits_past_the_requests_deadline(server, monkeypatch):
    """A server that keeps closing connections, a 1 s deadline and backoff from 0.4 s: the client retries after
    0.4 s, then gives up rather than wait 0.8 s more (the request would end at 1.2 s, past its deadline). The
    backoff runs on a fake clock, so the test measures the client's arithmetic, not the machine's speed."""
    import sagebench.http_client as http_client

    slept: list[float] = []
    clock = types.SimpleNamespace(monotonic=lambda: time.monotonic() + sum(slept), sleep=slept.append)
    monkeypatch.setattr(http_client, "time", clock)
    s = server("close")
    content_type, data = body()
    start = clock.monotonic()
    with pytest.raises(RequestFailed, match="^connection error: RemoteDisconnected"):
        post(s.url, data, content_type, timeout=1.0, retries=5, backoff=0.4)
    assert clock.monotonic() - start <= 1.0 + 0.5  # the real attempts take milliseconds of it
    assert slept == [0.4] and s.requests == 2


def test_a_refused_connection_fails_within_the_deadline():
    content_type, data = body()
    with pytest.raises(RequestFailed, match="^connection error: ConnectionRefusedError"):
        post("http://127.0.0.1:9/act", data, content_type, timeout=30.0, retries=1)


def test_a_reply_nested_too_deep_fails_its_slot_and_not_the_rollout(server):
    s = server("deep")
    policy = HttpPolicy(s.url, timeout=30.0)
    policy.begin([episode("ep-a")])
    (failure,) = policy.act([0], [OBS], [{"steps": 0}])
    assert failure.reason == f"policy {s.url} (step 0): the reply's JSON is nested deeper than 64 levels"


def episode(eid: str) -> Episode:
    z = np.zeros(3)
    return Episode(eid, "s", "low", "Base_Action", z, 0.0, z, 1.0, 1.0, np.zeros((2, 4)))


def test_a_failed_request_fails_its_slot_only_and_ids_are_opaque_per_rollout(server):
    s = server("status500", faulty=lambda n: n == 2)
    policy = HttpPolicy(s.url, timeout=30.0, workers=1)
    policy.begin([episode("ep-a"), episode("ep-b"), episode("ep-c")])
    infos = [{"steps": 0}] * 3
    actions = policy.act([0, 1, 2], [OBS] * 3, infos)
    assert actions[0] == actions[2] == Action.MOVE_FORWARD and isinstance(actions[1], PolicyFailure)
    assert actions[1].reason == f"policy {s.url} (step 0): HTTP 500 policy crashed"
    sent = [fields["episode_id"] for fields, _ in s.seen]
    assert sent == policy.ids[::2] and all(len(i) == 16 and not i.startswith("ep") for i in policy.ids)
    other = HttpPolicy(s.url)
    other.begin([episode("ep-a")])
    assert policy.opaque_id("ep-a") == policy.ids[0] != other.ids[0]  # stable in a rollout, new in the next
    policy.close()
