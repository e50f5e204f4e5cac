"""A policy served over HTTP: each step, one POST per running episode; the reply is the action.

Request body (JSON): {"episode_id": str, "step": int, "instruction": str, "pose": [x, y, z, yaw],
"collided": bool, "action_space": "discrete" | "continuous", "observations": {"rgb": {"encoding": "png",
"data": base64}, "depth": {"encoding": "npy", "data": base64}, "instance": {"encoding": "npy", ...}}}
(the images the rollout renders; depth float32 metres, instance int32).
Reply (JSON): {"action": "STOP" | "MOVE_FORWARD" | "TURN_LEFT" | "TURN_RIGHT"} (or 0..3) for discrete,
{"action": [v, omega, stop]} for continuous. Requests for the episodes of one step go out concurrently on up
to `workers` threads; the actions are used in slot order, so the results do not depend on the thread count.
"""

from __future__ import annotations

import base64
import io
import json
import urllib.error
import urllib.request
from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor

import cv2
import numpy as np

from sagebench.errors import SagebenchError
from sagebench.evaluation.scoring import Episode
from sagebench.navsim.actions import Action


class PolicyError(SagebenchError):
    """The policy server failed or answered something that is not an action (exit 1: not the user's input)."""

    exit_code = 1


def encode_observation(obs: dict, *, episode_id: str, step: int, action_space: str) -> dict:
    """The JSON request body for one observation (module docstring)."""
    images = {}
    if "rgb" in obs:
        ok, buf = cv2.imencode(".png", obs["rgb"][:, :, ::-1])
        images["rgb"] = {"encoding": "png", "data": base64.b64encode(buf.tobytes()).decode("ascii")}
    for key in ("depth", "instance"):
        if key in obs:
            raw = io.BytesIO()
            np.save(raw, obs[key], allow_pickle=False)
            images[key] = {"encoding": "npy", "data": base64.b64encode(raw.getvalue()).decode("ascii")}
    return {"episode_id": episode_id, "step": step, "instruction": obs["instruction"],
            "pose": [float(v) for v in obs["pose"]], "collided": bool(obs["collided"]),
            "action_space": action_space, "observations": images}


def decode_image(item: dict) -> np.ndarray:
    """An image of a request body back to an array (for policy servers written in Python)."""
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


class HttpPolicy:
    """POSTs observations to `url` (module docstring)."""

    def __init__(self, url: str, *, action_space: str = "discrete", timeout: float = 60.0, workers: int = 1):
        self.url, self.action_space, self.timeout, self.workers = url, action_space, timeout, max(1, workers)

    def begin(self, episodes: Sequence[Episode]) -> None:
        self.ids = [e.episode_id for e in episodes]

    def _ask(self, body: dict):
        req = urllib.request.Request(self.url, data=json.dumps(body).encode("utf-8"), method="POST",
                                     headers={"Content-Type": "application/json"})
        where = f"policy {self.url} (episode {body['episode_id']}, step {body['step']})"
        try:
            with urllib.request.urlopen(req, timeout=self.timeout) as resp:
                text = resp.read().decode("utf-8")
        except urllib.error.HTTPError as err:
            raise PolicyError(f"{where}: HTTP {err.code} {err.reason}") from None
        except (urllib.error.URLError, OSError) as err:
            raise PolicyError(f"{where}: {getattr(err, 'reason', err)}") from None
        try:
            return parse_action(json.loads(text), self.action_space)
        except ValueError as err:
            raise PolicyError(f"{where}: {err}") from None

    def act(self, slots, observations, infos) -> list:
        bodies = [encode_observation(o, episode_id=self.ids[i], step=info["steps"], action_space=self.action_space)
                  for i, o, info in zip(slots, observations, infos)]
        if self.workers == 1 or len(bodies) == 1:
            return [self._ask(b) for b in bodies]
        with ThreadPoolExecutor(self.workers) as pool:
            return list(pool.map(self._ask, bodies))
