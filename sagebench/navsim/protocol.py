"""The policy protocol's bodies: one observation as an HTTP request (three encodings), and the action a reply holds.

Every request carries the same fields: `episode_id` (opaque: a different id per rollout, so a policy cannot look
the episode up in the run's files), `step`, `action_space`, `profile`, `instruction` and, as the profile says,
`instruction_tokens`, `pose`, `gps`, `compass`, `collided`, the task's `pointgoal` or `objectgoal` (JSON
values), and the images: the profile's and imagenav's `imagegoal` ([H, W, 3] uint8, encoded as rgb is).
Encodings of the images:
- `raw` (the default), Content-Type application/x-sagebench-frame: a 4-byte little-endian length N, N bytes of
  UTF-8 JSON (the fields above plus `arrays`: name -> {"dtype", "shape", "encoding": "raw", "offset",
  "length"}), then the arrays' bytes, little-endian, C order, at those offsets after the header;
- `png`: the same frame with the colour images (rgb, imagegoal) as PNG bytes (`"encoding": "png"`), the rest raw;
- `json` (sagebench 0.x's), Content-Type application/json: the fields plus `observations`: name ->
  {"encoding": "png" (rgb, imagegoal) | "npy", "data": base64}.
A reply is JSON {"action": "STOP" | "MOVE_FORWARD" | "TURN_LEFT" | "TURN_RIGHT" | 0..3} (discrete) or
{"action": [v, omega, stop]} (continuous). `decode_request` reads all three, for policy servers in Python.
"""

from __future__ import annotations

import base64
import io
import json
import struct
from collections.abc import Mapping

import cv2
import numpy as np

from sagebench.episodes.preview import png_bytes
from sagebench.http_client import parse_json
from sagebench.navsim.actions import Action
from sagebench.settings.rollout import Encoding

ENCODINGS: tuple[str, ...] = ("raw", "png", "json")
FRAME_TYPE = "application/x-sagebench-frame"
JSON_TYPE = "application/json"
_LENGTH = struct.Struct("<I")
IMAGES = ("rgb", "depth", "instance", "imagegoal")  # sent as arrays, never as JSON lists
COLOUR = ("rgb", "imagegoal")  # [H, W, 3] uint8: PNG in the png and json encodings


def request_fields(obs: Mapping, *, episode_id: str, step: int, action_space: str, profile: str) -> dict:
    """The JSON fields of a request: everything of `obs` but its images, as JSON values."""
    fields = {"episode_id": episode_id, "step": int(step), "action_space": action_space, "profile": profile}
    for key, value in obs.items():
        if key in IMAGES:
            continue
        if isinstance(value, np.ndarray):
            fields[key] = value.tolist()
        elif isinstance(value, np.bool_ | bool):
            fields[key] = bool(value)
        else:
            fields[key] = value
    return fields


def encode_request(obs: Mapping, fields: dict, encoding: Encoding = "raw") -> tuple[str, bytes]:
    """(Content-Type, body) of one request: `fields` (request_fields) and the images of `obs`."""
    images = {k: np.asarray(obs[k]) for k in IMAGES if k in obs}
    if encoding == "json":
        encoded = {}
        for key, a in images.items():
            if key in COLOUR:
                encoded[key] = {"encoding": "png", "data": base64.b64encode(png_bytes(a)).decode("ascii")}
            else:
                raw = io.BytesIO()
                np.save(raw, a, allow_pickle=False)
                encoded[key] = {"encoding": "npy", "data": base64.b64encode(raw.getvalue()).decode("ascii")}
        return JSON_TYPE, json.dumps({**fields, "observations": encoded}).encode("utf-8")
    arrays, chunks, offset = {}, [], 0
    for key, a in images.items():
        if key in COLOUR and encoding == "png":
            data, how = png_bytes(a), "png"
        else:
            data, how = np.ascontiguousarray(a, a.dtype.newbyteorder("<")).tobytes(), "raw"
        arrays[key] = {"dtype": a.dtype.newbyteorder("<").str, "shape": list(a.shape), "encoding": how,
                       "offset": offset, "length": len(data)}
        chunks.append(data)
        offset += len(data)
    header = json.dumps({**fields, "arrays": arrays}).encode("utf-8")
    return FRAME_TYPE, b"".join([_LENGTH.pack(len(header)), header, *chunks])


def decode_request(content_type: str, body: bytes) -> tuple[dict, dict[str, np.ndarray]]:
    """(fields, images) of a request body in any encoding; a malformed body is a ValueError saying what."""
    kind = content_type.split(";")[0].strip().lower()
    if kind == JSON_TYPE:
        fields = parse_json(body)
        if not isinstance(fields, dict):
            raise ValueError("a JSON request must be an object")
        return ({k: v for k, v in fields.items() if k != "observations"},
                {k: decode_image(v) for k, v in fields.get("observations", {}).items()})
    if kind != FRAME_TYPE:
        raise ValueError(f"Content-Type {content_type!r} is neither {FRAME_TYPE} nor {JSON_TYPE}")
    if len(body) < _LENGTH.size:
        raise ValueError("frame shorter than its length prefix")
    (n,) = _LENGTH.unpack_from(body)
    start = _LENGTH.size + n
    fields = parse_json(body[_LENGTH.size: start])
    if not isinstance(fields, dict) or not isinstance(fields.get("arrays"), dict):
        raise ValueError("a frame's header has no 'arrays'")
    images = {}
    for key, spec in fields.pop("arrays").items():
        data = body[start + spec["offset"]: start + spec["offset"] + spec["length"]]
        if len(data) != spec["length"]:
            raise ValueError(f"array {key!r} runs past the end of the body")
        if spec["encoding"] == "png":
            images[key] = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_COLOR)[:, :, ::-1].copy()
        else:
            images[key] = np.frombuffer(data, np.dtype(spec["dtype"])).reshape(spec["shape"]).copy()
    return fields, images


def decode_image(item: Mapping) -> np.ndarray:
    """One image of a `json` body back to an array."""
    data = base64.b64decode(item["data"])
    if item["encoding"] == "png":
        return cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_COLOR)[:, :, ::-1]
    return np.load(io.BytesIO(data), allow_pickle=False)


def parse_action(reply: object, action_space: str):
    """The action of a reply body; a ValueError says what is wrong."""
    if not isinstance(reply, dict) or "action" not in reply:
        raise ValueError('expected a JSON object with "action"')
    a = reply["action"]
    if action_space == "discrete":
        if isinstance(a, str) and a in Action.__members__:
            return Action[a]
        if isinstance(a, int) and not isinstance(a, bool) and a in [int(x) for x in Action]:
            return Action(a)
        raise ValueError(f"action {a!r} is not one of {', '.join(Action.__members__)} (or 0..3)")
    if isinstance(a, list) and len(a) == 3 and all(isinstance(v, int | float) and not isinstance(v, bool) for v in a):
        return [float(v) for v in a]
    raise ValueError(f"action {a!r} is not [v, omega, stop]")


