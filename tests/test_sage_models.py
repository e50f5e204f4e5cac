"""`rollout --policy sage+http://` / `sage+socket://` against fake SAGE-Bench model servers written from the request
handling of SAGE-3D's evaluation_model/ servers (navila_server.py: socket, 8-byte big-endian length + JSON
{images, query}, answers json.dumps(text); mllm_server.py: the same frame, answers {status, result,
inference_time}; a NaVid-format HTTP /vln_step answering {result}; a NavDP/NoMaD-style HTTP /nogoal_step reading a
JPEG and a uint16 depth PNG and answering {trajectory}). What reaches the server is compared byte for byte with
what SAGE's client (vlm_client_modular.py) would send for the same frames, re-implemented here from its logic, and
the motions with its parsers re-implemented here, on 100 answers of each kind."""

from __future__ import annotations

import base64
import io
import json
import math
import random
import re
import socket
import threading
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer

import cv2
import numpy as np
import pytest
from PIL import Image

from sagebench.navsim.sage_policy import SagePolicy
from sagebench.navsim.sage_protocol import parse_text, parse_trajectory, reply_text

# ---- SAGE's client, re-implemented from vlm_client_modular.py's logic ------------------------------------------


def sage_pil_b64(frame: np.ndarray) -> str:
    buf = io.BytesIO()
    Image.fromarray(frame).convert("RGB").save(buf, format="JPEG")  # PIL's default quality
    return base64.b64encode(buf.getvalue()).decode()


def sage_socket_request(frames_so_far: list[np.ndarray], query: str) -> bytes:
    """RGBInputProcessor (history of 8, front-padded with the oldest) + SocketProtocol._send_rgb_request."""
    history = frames_so_far[-8:]
    while len(history) < 8:
        history.insert(0, history[0])
    data = json.dumps({"images": [sage_pil_b64(f) for f in history], "query": query}).encode("utf-8")
    return len(data).to_bytes(8, "big") + data


def sage_vln_step_request(frame: np.ndarray, instruction: str) -> bytes:
    """HTTPProtocol._send_rgb_request, as requests' json= serialises it."""
    return json.dumps({"images": [sage_pil_b64(frame)], "instruction": instruction, "current_yaw": 0.0},
                      allow_nan=False).encode("utf-8")


def sage_nogoal_parts(frame: np.ndarray, depth: np.ndarray) -> list[tuple[bytes, bytes]]:
    """HTTPProtocol._send_rgbd_request's files (cv2 path): (headers, data) of image then depth."""
    jpg = cv2.imencode(".jpg", cv2.cvtColor(frame, cv2.COLOR_RGB2BGR))[1].tobytes()
    png = cv2.imencode(".png", (np.clip(depth.astype(np.float32), 0.0, 6.5) * 10000.0).astype(np.uint16))[1].tobytes()
    return [(b'Content-Disposition: form-data; name="image"; filename="image.jpg"\r\nContent-Type: image/jpeg', jpg),
            (b'Content-Disposition: form-data; name="depth"; filename="depth.png"\r\nContent-Type: image/png', png)]


def sage_text_motion(raw) -> dict:
    """TextOutputParser.parse_output: a dict's text_response else str(raw); its keyword and regex rules."""
    text = raw.get("text_response", str(raw)) if isinstance(raw, dict) else str(raw)
    low = text.lower()
    action = {"vx": 0.0, "vy": 0.0, "yaw_rate": 0.0, "duration_s": 1.0, "stop": False}
    if any(w in low for w in ["stop", "halt", "complete", "finish", "done"]):
        action["stop"] = True
        return action
    if any(w in low for w in ["forward", "ahead", "straight", "move"]):
        m = re.search(r"(\d+\.?\d*)\s*(?:meter|metre|m|step)", low)
        action["vx"] = min(float(m.group(1)) / 1.0, 0.5) if m else 0.3
    left, right = "left" in low, "right" in low
    if left or right:
        m = re.search(r"(\d+\.?\d*)\s*(?:degree|deg|°)", low)
        rad = math.radians(float(m.group(1))) if m else math.radians(30)
        action["yaw_rate"] = rad / 1.0 if left else -rad / 1.0
    if any(w in low for w in ["back", "backward", "reverse"]):
        action["vx"] = -0.2
    return action


def sage_trajectory_motion(trajectory: np.ndarray, current_yaw: float) -> tuple[float, float, float]:
    """TrajectoryOutputParser._parse_trajectory_to_velocity."""
    yaw_rate = 0.0
    if len(trajectory) >= 3:
        directions = []
        for i in range(min(5, len(trajectory) - 1)):
            dx = trajectory[i + 1][0] - trajectory[i][0]
            dy = trajectory[i + 1][1] - trajectory[i][1]
            if np.sqrt(dx * dx + dy * dy) > 0.005:
                directions.append(math.atan2(dy, dx))
        if len(directions) >= 2:
            changes = []
            for i in range(len(directions) - 1):
                d = directions[i + 1] - directions[i]
                while d > math.pi:
                    d -= 2 * math.pi
                while d < -math.pi:
                    d += 2 * math.pi
                changes.append(d)
            yaw_rate = np.clip(np.mean(changes) * 2.0, -math.radians(60), math.radians(60))
    for point in trajectory:
        x, y, _ = point[:3]
        if np.sqrt(x * x + y * y) > 0.01:
            rvx, rvy = float(-x * 3.0), float(y * 3.0)
            wvx = rvx * math.cos(current_yaw) - rvy * math.sin(current_yaw)
            wvy = rvx * math.sin(current_yaw) + rvy * math.cos(current_yaw)
            speed = np.sqrt(wvx * wvx + wvy * wvy)
            if speed > 0.5:
                wvx, wvy = wvx * 0.5 / speed, wvy * 0.5 / speed
            return wvx, wvy, yaw_rate
    return 0.0, 0.0, yaw_rate


# ---- answers --------------------------------------------------------------------------------------------------

PROSE = ["I can see a hallway ahead. I will move forward about 1.5 meters and then turn right.",
         "The sofa is on my left, so I should turn left by 45 degrees to face the kitchen.",
         "The goal seems reached; I am done.", "Looking around... nothing matches the instruction yet.",
         "Go straight ahead 2 steps", "Let me back up a little, the way is blocked.", "TURN_RIGHT", "MOVE_FORWARD",
         "turn right 15°", "I'd walk 0.8m then veer right"]


def answers(n: int, seed: int = 0) -> list:
    """n answers as SAGE's servers send them: NaVILA's text, MLLM prose and tokens, NaVid's and the MLLM
    server's objects."""
    rng = random.Random(seed)
    out = []
    for k in range(n):
        kind = k % 6
        if kind == 0:
            out.append(f"The next action is move forward {rng.choice([25, 50, 75])} cm")
        elif kind == 1:
            out.append(f"turn {rng.choice(['left', 'right'])} {rng.choice([15, 30, 45, 90])} degrees")
        elif kind == 2:
            out.append(f"move forward {rng.choice([0.25, 0.5, 0.75, 1.25])} meter")
        elif kind == 3:
            out.append(rng.choice(PROSE))
        elif kind == 4:
            out.append({"status": "success", "result": rng.choice(["MOVE_FORWARD", "TURN_LEFT", "TURN_RIGHT", "STOP"]),
                        "inference_time": round(rng.uniform(0.1, 3), 3)})
        else:
            out.append({"vx": 0.25, "stop": False, "text_response": rng.choice(PROSE), "status": "success"})
    return out


def trajectories(n: int, seed: int = 0) -> list[np.ndarray]:
    rng = np.random.default_rng(seed)
    out = []
    for k in range(n):
        steps = rng.normal([-0.1, 0.0, 0.0], [0.05, 0.08, 0.01], size=(int(rng.integers(1, 9)), 3))
        if k % 7 == 0:
            steps[: 2] = 0.001  # waypoints within 1 cm / segments under 5 mm at the start
        points = np.cumsum(steps, axis=0)
        out.append(points[None] if k % 3 == 0 else points)
    return out


def test_parsers_match_sages_on_100_answers():
    """Every text answer (NaVILA, MLLM prose and tokens, the servers' objects) and every trajectory moves the
    agent exactly as SAGE's TextOutputParser / TrajectoryOutputParser say (current_yaw any)."""
    for raw in answers(100):
        got, want = parse_text(reply_text(raw)), sage_text_motion(raw)
        assert (got.vx, got.vy, got.yaw_rate, got.duration_s, got.stop) == tuple(want.values()), raw
    rng = np.random.default_rng(1)
    for points in trajectories(100):
        yaw = float(rng.uniform(-math.pi, math.pi))
        flat = points[0] if points.ndim == 3 else points
        got = parse_trajectory(flat, yaw)
        assert (got.vx, got.vy, got.yaw_rate, got.duration_s, got.stop) == (*sage_trajectory_motion(flat, yaw), 1.0,
                                                                            False)


# ---- fake servers, from SAGE's evaluation_model/ request handling ----------------------------------------------


class SocketServer:
    """navila_server.py / mllm_server.py: one request per connection, framed both ways; `answer(n, request)`
    gives the reply object (json.dumps'd), or bytes sent as they are."""

    def __init__(self, answer):
        self.answer, self.frames = answer, []
        self.sock = socket.create_server(("127.0.0.1", 0))
        self.url = f"sage+socket://127.0.0.1:{self.sock.getsockname()[1]}"
        threading.Thread(target=self._serve, daemon=True).start()

    def _serve(self) -> None:
        while True:
            try:
                conn, _ = self.sock.accept()
            except OSError:
                return
            with conn:
                head = self._exactly(conn, 8)
                body = self._exactly(conn, int.from_bytes(head, "big"))
                request = json.loads(body.decode())
                assert set(request) == {"images", "query"}
                self.frames.append(head + body)
                reply = self.answer(len(self.frames), request)
                data = reply if isinstance(reply, bytes) else json.dumps(reply).encode()
                conn.sendall(data if isinstance(reply, bytes) else len(data).to_bytes(8, "big") + data)

    @staticmethod
    def _exactly(conn: socket.socket, n: int) -> bytes:
        data = b""
        while len(data) < n:
            data += conn.recv(n - len(data))
        return data

    def close(self) -> None:
        self.sock.close()


class HttpServer:
    """A NaVid-format /vln_step ({images, instruction, current_yaw} -> {result}) and a NavDP/NoMaD-style
    /nogoal_step (multipart image + depth -> {trajectory}); `answer(n, path, request)` -> reply object."""

    def __init__(self, answer):
        self.answer, self.requests = answer, []
        outer = self

        class Handler(BaseHTTPRequestHandler):
            def do_POST(self):  # noqa: N802 - http.server's name
                body = self.rfile.read(int(self.headers["Content-Length"]))
                outer.requests.append((self.path, self.headers["Content-Type"], body))
                reply = json.dumps(outer.answer(len(outer.requests), self.path, decode(self.path, self.headers,
                                                                                        body))).encode()
                self.send_response(200)
                self.send_header("Content-Type", "application/json")
                self.send_header("Content-Length", str(len(reply)))
                self.end_headers()
                self.wfile.write(reply)

            def log_message(self, *args):
                pass

        self.httpd = ThreadingHTTPServer(("127.0.0.1", 0), Handler)
        self.origin = f"127.0.0.1:{self.httpd.server_address[1]}"
        threading.Thread(target=self.httpd.serve_forever, daemon=True).start()

    def close(self) -> None:
        self.httpd.shutdown()
        self.httpd.server_close()


def multipart(content_type: str, body: bytes) -> list[tuple[bytes, bytes]]:
    boundary = content_type.split("boundary=")[1].encode()
    parts = body.split(b"--" + boundary)
    assert parts[0] == b"" and parts[-1] == b"--\r\n"
    return [tuple(p[2:-2].split(b"\r\n\r\n", 1)) for p in parts[1:-1]]


def decode(path: str, headers, body: bytes) -> dict:
    """What SAGE's servers read of a request: the images decoded (a server would fail on anything else)."""
    if path == "/vln_step":
        request = json.loads(body)
        assert set(request) == {"images", "instruction", "current_yaw"}
        request["frames"] = [np.array(Image.open(io.BytesIO(base64.b64decode(i))).convert("RGB"))
                             for i in request["images"]]
        return request
    parts = dict(zip(("image", "depth"), (data for _, data in multipart(headers["Content-Type"], body))))
    depth = cv2.imdecode(np.frombuffer(parts["depth"], np.uint8), cv2.IMREAD_UNCHANGED)
    assert depth.dtype == np.uint16 and depth.max() <= 65000
    return {"depth_m": depth.astype(np.float32) / 10000.0}


@pytest.fixture
def servers():
    made = []

    def start(cls, answer):
        made.append(cls(answer))
        return made[-1]

    yield start
    for s in made:
        s.close()


@pytest.fixture
def seen(monkeypatch):
    """What the policy saw each time it asked its server (rgb, depth, instruction), and each action it gave."""
    log = {"asked": [], "actions": []}
    ask, act = SagePolicy._ask, SagePolicy.act

    def spy_ask(self, slot, obs):
        log["asked"].append((slot, np.array(obs["rgb"]), np.array(obs["depth"]), obs["instruction"]))
        return ask(self, slot, obs)

    def spy_act(self, slots, observations, infos):
        before = len(log["asked"])
        out = act(self, slots, observations, infos)
        assert len(slots) == 1  # SAGE's servers serve one episode at a time
        log["actions"].append((len(log["asked"]) > before, out[0]))
        return out

    monkeypatch.setattr(SagePolicy, "_ask", spy_ask)
    monkeypatch.setattr(SagePolicy, "act", spy_act)
    return log


ARGS = ("--episodes", "2", "--width", "64", "--height", "48", "--max-steps", "40", "--workers", "1")


def rollout(run_cli, tiny_run, tmp_path, url: str, *extra: str):
    out = tmp_path / "pred.jsonl"
    code, stdout, err = run_cli("rollout", "--run", tiny_run, "--out", out, "--policy", url, *ARGS, *extra)
    return code, stdout, err, [json.loads(line) for line in out.read_text().splitlines()] if out.exists() else []


@pytest.mark.parametrize("mllm", [False, True], ids=["navila", "mllm"])
def test_a_socket_text_server_gets_sages_8_frame_requests_and_moves_the_agent_as_sage_parses(
        servers, seen, run_cli, tiny_run, tmp_path, mllm):
    script = ["The next action is turn left 30 degrees", "move forward 0.75 meter", "turn right 15 degrees",
              "Move forward 25 cm", "MOVE_FORWARD", "TURN_LEFT", "I will move forward 0.5 m towards the door",
              "halt, the task is complete"]

    def answer(n, request):
        text = script[(n - 1) % len(script)]
        return {"status": "success", "result": text, "inference_time": 0.5} if mllm else text

    server = servers(SocketServer, answer)
    code, stdout, err, rows = rollout(run_cli, tiny_run, tmp_path, server.url)
    assert code == 0, stdout + err
    assert len(rows) == 2 and all(r["stopped"] for r in rows)
    # request bytes: SAGE's client for each episode's frames so far, 8 of them, oldest first
    assert len(server.frames) == len(seen["asked"]) == 2 * len(script)
    for episode in (0, 1):
        asked = seen["asked"][episode * len(script): (episode + 1) * len(script)]
        for k, (_, rgb, _, text) in enumerate(asked):
            frames = [a[1] for a in asked[: k + 1]]
            assert server.frames[episode * len(script) + k] == sage_socket_request(frames, text)
    # motions: each answer's command, translation then turn, at the speed and turn-rate limits
    expect = [sage_text_motion(answer(n, None)) for n in range(1, len(script) + 1)] * 2
    driven = commands(seen["actions"])
    assert len(driven) == len(expect)
    for (distance, turn, stop), want in zip(driven, expect):
        assert stop == want["stop"]
        assert distance == pytest.approx(max(want["vx"], 0.0) * want["duration_s"], abs=1e-12)
        assert turn == pytest.approx(want["yaw_rate"] * want["duration_s"], abs=1e-12)


def commands(actions: list[tuple[bool, list]], interval: float = 0.5) -> list[tuple[float, float, bool]]:
    """The policy's actions regrouped by the server answer they carry out: (metres driven, radians turned, stop)."""
    out: list[list] = []
    for asked, (v, omega, stop) in actions:
        if asked:
            out.append([0.0, 0.0, False])
        out[-1][0] += v * interval
        out[-1][1] += omega * interval
        out[-1][2] = out[-1][2] or stop >= 0.5
    return [tuple(c) for c in out]


def test_http_servers_get_sages_vln_step_and_nogoal_step_requests_and_moves_follow_the_answers(
        servers, seen, run_cli, tiny_run, tmp_path):
    """A NaVid-format /vln_step server answering free MLLM prose, then a NoMaD-style /nogoal_step server answering
    trajectories: each request is SAGE's for the current frame (and depth), each motion SAGE's parser's."""
    prose = PROSE[:2] + PROSE[4:6] + ["The task is done."]
    text = servers(HttpServer, lambda n, path, request: {"result": prose[(n - 1) % len(prose)]})
    code, stdout, err, rows = rollout(run_cli, tiny_run, tmp_path, f"sage+http://{text.origin}")
    assert code == 0 and len(rows) == 2 and all(r["stopped"] for r in rows), stdout + err
    assert [(p, t) for p, t, _ in text.requests] == [("/vln_step", "application/json")] * len(seen["asked"])
    assert [b for _, _, b in text.requests] == [sage_vln_step_request(rgb, i) for _, rgb, _, i in seen["asked"]]
    want = [sage_text_motion({"text": prose[n % len(prose)]}) for n in range(len(seen["asked"]))]
    assert commands(seen["actions"]) == [pytest.approx((max(w["vx"], 0), w["yaw_rate"], w["stop"])) for w in want]

    paths = trajectories(12, seed=3)
    seen["asked"].clear()
    seen["actions"].clear()
    nomad = servers(HttpServer, lambda n, path, request: {"trajectory": paths[(n - 1) % len(paths)].tolist()})
    code, stdout, err, rows = rollout(run_cli, tiny_run, tmp_path / "b", f"sage+http://{nomad.origin}/nogoal_step",
                                      "--max-steps", "12")
    assert code == 0 and len(rows) == 2 and not any(r["stopped"] for r in rows), stdout + err
    for (path, content_type, body), (_, rgb, depth, _) in zip(nomad.requests, seen["asked"], strict=True):
        assert path == "/nogoal_step" and multipart(content_type, body) == sage_nogoal_parts(rgb, depth)
    assert any(d.max() > 0 for _, _, d, _ in seen["asked"])
    got = commands(seen["actions"])
    for n, (distance, turn, stop) in enumerate(got[:-1] if len(got) > 1 else got):
        points = paths[n % len(paths)]
        vx, _, yaw_rate = sage_trajectory_motion(points[0] if points.ndim == 3 else points, 0.0)
        assert (distance, turn, stop) == pytest.approx((max(vx, 0.0), yaw_rate, False))


@pytest.mark.parametrize("transport, reply, message", [
    ("http", {"action": "MOVE_FORWARD"}, '/vln_step answered no {"result": text} (SAGE\'s client would move forward)'),
    ("nogoal", {"trajectory": [[0.1, 0.2]]}, "/nogoal_step's reply: its trajectory has shape [1, 2], not [N, 3] "
                                             "waypoints (x, y, z)"),
    ("nogoal", {"path": []}, '/nogoal_step answered no {"trajectory": [[x, y, z], ...]}'),
    ("socket", {"status": "error", "message": "VLN query failed: CUDA out of memory", "result": "MOVE_FORWARD"},
     "the server reports an error: VLN query failed: CUDA out of memory"),
    ("socket", {"status": "reset_complete"}, 'its reply is neither text nor an object with "result" or '
                                             '"text_response"'),
    ("socket", b"\x00\x00\x00\x00\x00\x00\x01\x00{", "the server closed the connection after 1 of the 256 bytes of "
                                                     "its reply"),
])
def test_a_bad_reply_fails_its_episode_with_one_line_naming_the_server(servers, run_cli, tiny_run, tmp_path,
                                                                       transport, reply, message):
    """SAGE's client would stop or move on silently; here the episode fails by the policy, visibly."""
    if transport == "socket":
        server = servers(SocketServer, lambda n, request: reply)
        url = server.url
    else:
        server = servers(HttpServer, lambda n, path, request: reply)
        url = f"sage+http://{server.origin}" + ("/nogoal_step" if transport == "nogoal" else "")
    code, stdout, err, rows = rollout(run_cli, tiny_run, tmp_path, url, "--max-policy-failures", "5")
    assert code == 1 and rows == []
    failed = [line for line in stdout.splitlines() if "FAILED by the policy" in line]
    assert len(failed) == 2 and all(line.endswith(f"SAGE model server {url} (step 0): {message}") for line in failed)


@pytest.mark.parametrize("args, message", [
    (("--policy", "sage+http://127.0.0.1:9/act"), "error: --policy: SAGE's HTTP endpoints are /vln_step and "
                                                  "/nogoal_step, not '/act'"),
    (("--policy", "sage+socket://127.0.0.1"), "error: --policy: 'sage+socket://127.0.0.1' must be "
                                              "sage+socket://HOST:PORT"),
    (("--policy", "sage+socket://127.0.0.1:9", "--action-space", "discrete"),
     "error: --action-space: a SAGE model server's answers are velocities: --action-space continuous"),
    (("--policy", "sage+socket://127.0.0.1:9", "--preset", "vlnce"),
     "error: --profile: a SAGE model server gets SAGE's observations: --profile sage"),
])
def test_a_sage_policy_that_cannot_run_is_one_line_exit_2_and_writes_nothing(run_cli, tiny_run, tmp_path, args,
                                                                             message):
    code, stdout, err = run_cli("rollout", "--run", tiny_run, "--out", tmp_path / "p.jsonl", *args)
    assert code == 2 and err.strip() == message, err
    assert list(tmp_path.iterdir()) == []
