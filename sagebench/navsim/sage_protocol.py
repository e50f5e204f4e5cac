"""SAGE-Bench's model protocol, the client side (SAGE-3D's vlm_client_modular.py): the bytes its client sends and
the motion its parsers read from a reply. No I/O here (navsim/sage_policy.py talks to the server).

Requests (docs/sage_models.md says where SAGE's own code is ambiguous and what is chosen):
- `/vln_step` (HTTP, RGB in, text out): JSON {"images": [base64 JPEG], "instruction", "current_yaw": 0.0}, the
  JPEG Pillow's default (quality 75), the JSON as `requests` writes it (json.dumps with allow_nan=False);
- `/nogoal_step` (HTTP, RGB-D in, trajectory out): multipart form `image` (image.jpg, OpenCV's JPEG of the BGR
  image, its default quality 95) and `depth` (depth.png, metres clipped to [0, 6.5] x 10000 as uint16, OpenCV's PNG);
- socket (RGB in, text out): an 8-byte big-endian length, then JSON {"images": [8 base64 JPEGs, oldest first],
  "query"}; the reply is framed the same way.
Parsers: SAGE's text regexes (`parse_text`) and trajectory-to-velocity rule (`parse_trajectory`), each giving a
`Command` (vx, vy m/s in the robot frame, yaw_rate rad/s counter-clockwise, held for duration_s; or stop).
"""

from __future__ import annotations

import base64
import io
import json
import math
import re
from collections import deque
from dataclasses import dataclass

import cv2
import numpy as np
from PIL import Image

HISTORY_FRAMES = 8  # the socket request's image history (SAGE's RGBInputProcessor)
DEPTH_CLIP_M = 6.5
DEPTH_SCALE = 10000.0  # depth PNG units per metre
COMMAND_S = 1.0  # every parsed command lasts 1 s
TEXT_MAX_SPEED = 0.5  # m/s, the text parser's cap on "move forward N meter"
TEXT_DEFAULT_SPEED = 0.3  # m/s, forward without a distance
TEXT_DEFAULT_TURN_DEG = 30.0
TEXT_BACK_SPEED = -0.2
TRAJECTORY_GAIN = 3.0  # velocity per metre of the first waypoint's offset
TRAJECTORY_MAX_SPEED = 0.5
TRAJECTORY_MAX_TURN = math.radians(60)
STOP_WORDS = ("stop", "halt", "complete", "finish", "done")
FORWARD_WORDS = ("forward", "ahead", "straight", "move")
BACK_WORDS = ("back", "backward", "reverse")
_DISTANCE = re.compile(r"(\d+\.?\d*)\s*(?:meter|metre|m|step)")
_ANGLE = re.compile(r"(\d+\.?\d*)\s*(?:degree|deg|°)")


@dataclass(frozen=True)
class Command:
    """One parsed answer: velocities held for duration_s (SAGE's env.apply_cmd_for), or stop."""

    vx: float = 0.0
    vy: float = 0.0
    yaw_rate: float = 0.0
    duration_s: float = COMMAND_S
    stop: bool = False


def jpeg_b64(rgb: np.ndarray) -> str:
    """An RGB frame as SAGE's RGB requests carry it: Pillow's JPEG at its default quality, base64."""
    out = io.BytesIO()
    Image.fromarray(np.asarray(rgb, dtype=np.uint8)).convert("RGB").save(out, format="JPEG")
    return base64.b64encode(out.getvalue()).decode("utf-8")


def vln_step_body(rgb: np.ndarray, instruction: str) -> bytes:
    """The JSON body of POST /vln_step for the current frame."""
    data = {"images": [jpeg_b64(rgb)], "instruction": instruction, "current_yaw": 0.0}
    return json.dumps(data, allow_nan=False).encode("utf-8")


def socket_frame(history: list[np.ndarray], instruction: str) -> bytes:
    """A socket request: the 8-byte big-endian length, then the JSON with the frames oldest first."""
    data = json.dumps({"images": [jpeg_b64(f) for f in history], "query": instruction}).encode("utf-8")
    return len(data).to_bytes(8, "big") + data


def depth_png(depth: np.ndarray) -> bytes:
    """Depth [H, W] metres as SAGE's RGB-D request carries it: clipped to 6.5 m, x 10000, uint16 PNG."""
    clipped = np.clip(np.asarray(depth, dtype=np.float32), 0.0, DEPTH_CLIP_M)
    return cv2.imencode(".png", (clipped * DEPTH_SCALE).astype(np.uint16))[1].tobytes()


def nogoal_step_body(rgb: np.ndarray, depth: np.ndarray, boundary: str) -> tuple[str, bytes]:
    """(Content-Type, body) of POST /nogoal_step: the form `requests` sends for files image and depth."""
    jpeg = cv2.imencode(".jpg", np.ascontiguousarray(np.asarray(rgb, dtype=np.uint8)[:, :, ::-1]))[1].tobytes()
    parts = [(b"image", b"image.jpg", b"image/jpeg", jpeg), (b"depth", b"depth.png", b"image/png", depth_png(depth))]
    mark = boundary.encode("ascii")
    body = b"".join(b"--%s\r\nContent-Disposition: form-data; name=\"%s\"; filename=\"%s\"\r\nContent-Type: %s\r\n\r\n"
                    b"%s\r\n" % (mark, name, filename, kind, data) for name, filename, kind, data in parts)
    return f"multipart/form-data; boundary={boundary}", body + b"--%s--\r\n" % mark


class History:
    """One episode's socket image history: the last 8 frames, padded at the front with the oldest."""

    def __init__(self) -> None:
        self.frames: deque[np.ndarray] = deque(maxlen=HISTORY_FRAMES)

    def add(self, rgb: np.ndarray) -> list[np.ndarray]:
        self.frames.append(np.array(rgb, dtype=np.uint8))
        return [self.frames[0]] * (HISTORY_FRAMES - len(self.frames)) + list(self.frames)


def reply_text(reply: object) -> str:
    """The text SAGE's text parser reads from a reply: an object's "text_response", else the reply as Python
    prints it (SAGE parses str() of the whole object, so keys and quoting take part)."""
    if isinstance(reply, dict) and "text_response" in reply:
        return str(reply["text_response"])
    return str(reply)


def parse_text(text: str) -> Command:
    """SAGE's text rule: a stop word stops; forward words move at the stated metres per second (capped) or 0.3;
    left / right turn the stated degrees (default 30) in 1 s; back words reverse at 0.2 m/s."""
    t = text.lower()
    if any(w in t for w in STOP_WORDS):
        return Command(stop=True)
    vx, yaw_rate = 0.0, 0.0
    if any(w in t for w in FORWARD_WORDS):
        found = _DISTANCE.search(t)
        vx = min(float(found[1]) / COMMAND_S, TEXT_MAX_SPEED) if found else TEXT_DEFAULT_SPEED
    left = "left" in t
    if left or "right" in t:
        found = _ANGLE.search(t)
        angle = math.radians(float(found[1]) if found else TEXT_DEFAULT_TURN_DEG)
        yaw_rate = (angle if left else -angle) / COMMAND_S
    if any(w in t for w in BACK_WORDS):
        vx = TEXT_BACK_SPEED
    return Command(vx=vx, yaw_rate=yaw_rate)


def trajectory_points(value: object) -> np.ndarray:
    """A reply's trajectory as [N, >=3] floats (a leading batch of one dropped); a ValueError says what is wrong."""
    try:
        points = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError("its trajectory is not an array of numbers") from None
    if points.ndim == 3 and points.shape[0] == 1:
        points = points[0]
    if points.ndim != 2 or points.shape[1] < 3 or not len(points):
        raise ValueError(f"its trajectory has shape {list(points.shape)}, not [N, 3] waypoints (x, y, z)")
    if not np.isfinite(points).all():
        raise ValueError("its trajectory holds a value that is not finite")
    return points


def parse_trajectory(points: np.ndarray, current_yaw: float = 0.0) -> Command:
    """SAGE's trajectory rule on [N, >=3] waypoints: the yaw rate is twice the mean change of heading between the
    first segments longer than 5 mm (clipped to 60 deg/s); the velocity is 3 x (-x, y) of the first waypoint
    farther than 1 cm from the origin, rotated by current_yaw and capped at 0.5 m/s."""
    headings = []
    if len(points) >= 3:
        for a, b in zip(points[:5], points[1:6]):
            dx, dy = b[0] - a[0], b[1] - a[1]
            if np.sqrt(dx * dx + dy * dy) > 0.005:
                headings.append(math.atan2(dy, dx))
    yaw_rate = 0.0
    if len(headings) >= 2:
        change = np.mean([math.remainder(h1 - h0, 2 * math.pi) for h0, h1 in zip(headings, headings[1:])])
        yaw_rate = float(np.clip(change * 2.0, -TRAJECTORY_MAX_TURN, TRAJECTORY_MAX_TURN))
    for x, y in points[:, :2]:
        if np.sqrt(x * x + y * y) > 0.01:
            rx, ry = float(-x * TRAJECTORY_GAIN), float(y * TRAJECTORY_GAIN)
            c, s = math.cos(current_yaw), math.sin(current_yaw)
            vx, vy = rx * c - ry * s, rx * s + ry * c
            speed = np.sqrt(vx * vx + vy * vy)
            if speed > TRAJECTORY_MAX_SPEED:
                vx, vy = vx * TRAJECTORY_MAX_SPEED / speed, vy * TRAJECTORY_MAX_SPEED / speed
            return Command(vx=vx, vy=vy, yaw_rate=yaw_rate)
    return Command(yaw_rate=yaw_rate)
