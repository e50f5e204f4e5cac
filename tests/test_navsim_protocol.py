"""The policy protocol's bodies: every encoding round-trips the observation exactly, the frame is laid out as
documented (read here with struct and numpy alone), sagebench 0.x's JSON body still decodes, bad bodies say why."""

from __future__ import annotations

import base64
import io
import json
import re
import struct

import cv2
import numpy as np
import pytest

from sagebench.navsim.actions import Action
from sagebench.navsim.protocol import (
    ENCODINGS, FRAME_TYPE, JSON_TYPE, decode_request, encode_request, parse_action, request_fields,
)


def observation(rng: np.random.Generator) -> dict:
    return {"rgb": rng.integers(0, 256, (6, 8, 3), dtype=np.uint8),
            "depth": rng.uniform(0, 1, (5, 7, 1)).astype(np.float32),
            "instance": rng.integers(-1, 900, (6, 8)).astype(np.int32),
            "instruction": "walk to the red chair", "instruction_tokens": np.arange(200, dtype=np.int64),
            "gps": np.array([1.5, -0.25], np.float32), "collided": np.bool_(True)}


@pytest.mark.parametrize("encoding", ENCODINGS)
def test_every_encoding_round_trips_the_observation_exactly(encoding):
    obs = observation(np.random.default_rng(0))
    fields = request_fields(obs, episode_id="ab12", step=3, action_space="discrete", profile="full")
    content_type, body = encode_request(obs, fields, encoding)
    got, images = decode_request(content_type + "; charset=utf-8", body)
    assert got == {"episode_id": "ab12", "step": 3, "action_space": "discrete", "profile": "full",
                   "instruction": "walk to the red chair", "instruction_tokens": list(range(200)),
                   "gps": [1.5, -0.25], "collided": True}
    assert set(images) == {"rgb", "depth", "instance"}
    for key in images:
        assert images[key].dtype == obs[key].dtype and images[key].tobytes() == obs[key].tobytes()


def test_the_raw_frame_is_a_length_a_json_header_and_little_endian_arrays():
    obs = {"rgb": np.zeros((2, 3, 3), np.uint8), "depth": np.array([[0.5, 2.0]], np.float32), "instruction": "go"}
    content_type, body = encode_request(obs, request_fields(obs, episode_id="e", step=0, action_space="discrete",
                                                            profile="custom"))
    (n,) = struct.unpack("<I", body[:4])
    header = json.loads(body[4: 4 + n])
    assert content_type == FRAME_TYPE and header["instruction"] == "go"
    assert header["arrays"] == {
        "rgb": {"dtype": "|u1", "shape": [2, 3, 3], "encoding": "raw", "offset": 0, "length": 18},
        "depth": {"dtype": "<f4", "shape": [1, 2], "encoding": "raw", "offset": 18, "length": 8}}
    assert body[4 + n + 18:] == struct.pack("<2f", 0.5, 2.0) and len(body) == 4 + n + 26


def test_png_frames_carry_rgb_as_png_and_the_rest_raw():
    obs = observation(np.random.default_rng(1))
    _, body = encode_request(obs, {"step": 0}, "png")
    (n,) = struct.unpack("<I", body[:4])
    arrays = json.loads(body[4: 4 + n])["arrays"]
    assert [a["encoding"] for a in arrays.values()] == ["png", "raw", "raw"]
    png = body[4 + n + arrays["rgb"]["offset"]: 4 + n + arrays["rgb"]["offset"] + arrays["rgb"]["length"]]
    assert cv2.imdecode(np.frombuffer(png, np.uint8), cv2.IMREAD_COLOR)[:, :, ::-1].tobytes() == obs["rgb"].tobytes()



@pytest.mark.parametrize("encoding, how", [("raw", "raw"), ("png", "png"), ("json", "png")])
def test_imagenavs_goal_image_travels_as_rgb_does_not_as_a_json_list(encoding, how):
    """imagegoal is an image: an array of the frame (PNG where rgb is PNG), never [H][W][3] in the JSON fields, and
    it decodes to the same uint8 array."""
    rng = np.random.default_rng(2)
    obs = {"rgb": rng.integers(0, 256, (6, 8, 3), dtype=np.uint8), "imagegoal": rng.integers(0, 256, (6, 8, 3),
                                                                                              dtype=np.uint8)}
    fields = request_fields(obs, episode_id="e", step=0, action_space="discrete", profile="custom")
    content_type, body = encode_request(obs, fields, encoding)
    if encoding == "json":
        specs = json.loads(body)["observations"]
    else:
        (n,) = struct.unpack("<I", body[:4])
        specs = json.loads(body[4: 4 + n])["arrays"]
    assert "imagegoal" not in fields and specs["imagegoal"]["encoding"] == specs["rgb"]["encoding"] == how
    _, images = decode_request(content_type, body)
    assert images["imagegoal"].dtype == np.uint8 and images["imagegoal"].tobytes() == obs["imagegoal"].tobytes()

def test_the_json_body_of_sagebench_0x_still_decodes():
    rgb = np.arange(24, dtype=np.uint8).reshape(2, 4, 3)
    raw = io.BytesIO()
    np.save(raw, np.ones((2, 4), np.float32))
    body = json.dumps({"episode_id": "x", "step": 1, "instruction": "go", "pose": [0, 0, 0, 0], "collided": False,
                       "action_space": "discrete", "observations": {
                           "rgb": {"encoding": "png", "data": base64.b64encode(
                               cv2.imencode(".png", rgb[:, :, ::-1])[1].tobytes()).decode()},
                           "depth": {"encoding": "npy", "data": base64.b64encode(raw.getvalue()).decode()}}}).encode()
    fields, images = decode_request(JSON_TYPE, body)
    assert fields["step"] == 1 and "observations" not in fields
    assert images["rgb"].tobytes() == rgb.tobytes() and images["depth"].tolist() == [[1.0] * 4] * 2


@pytest.mark.parametrize("content_type, body, message", [
    ("text/plain", b"{}", "Content-Type 'text/plain' is neither application/x-sagebench-frame nor application/json"),
    (FRAME_TYPE, b"\x01", "frame shorter than its length prefix"),
    (FRAME_TYPE, struct.pack("<I", 2) + b"{}", "a frame's header has no 'arrays'"),
])
def test_a_malformed_body_says_what_is_wrong(content_type, body, message):
    with pytest.raises(ValueError, match=f"^{re.escape(message)}$"):
        decode_request(content_type, body)


def test_an_array_past_the_end_of_the_body_is_refused():
    _, body = encode_request({"depth": np.zeros((4, 4), np.float32)}, {"step": 0})
    with pytest.raises(ValueError, match="^array 'depth' runs past the end of the body$"):
        decode_request(FRAME_TYPE, body[:-1])


@pytest.mark.parametrize("reply, space, expected", [
    ({"action": "TURN_LEFT"}, "discrete", Action.TURN_LEFT), ({"action": 0}, "discrete", Action.STOP),
    ({"action": [0.5, -1, 0]}, "continuous", [0.5, -1.0, 0.0]),
])
def test_replies_parse_to_actions(reply, space, expected):
    assert parse_action(reply, space) == expected


@pytest.mark.parametrize("reply, space, message", [
    ([], "discrete", 'expected a JSON object with "action"'),
    ({"action": True}, "discrete", "action True is not one of STOP, MOVE_FORWARD, TURN_LEFT, TURN_RIGHT (or 0..3)"),
    ({"action": [1, 2]}, "continuous", "action [1, 2] is not [v, omega, stop]"),
])
def test_bad_replies_say_why(reply, space, message):
    with pytest.raises(ValueError, match=f"^{re.escape(message)}$"):
        parse_action(reply, space)
