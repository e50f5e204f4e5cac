"""Opaque episode ids: what a policy (a server, an agent, a gym env's caller) is told in place of the run's episode
id, so it cannot look the episode (its goal, its reference path) up in the run's files. Each OpaqueIds draws a
random key: ids are stable for its lifetime (a rollout, an env) and differ between them."""

from __future__ import annotations

import hashlib
import hmac
import os


class OpaqueIds:
    def __init__(self):
        self._key = os.urandom(16)

    def __call__(self, episode_id: str) -> str:
        """HMAC-SHA256(key, episode_id), its first 16 hex digits."""
        return hmac.new(self._key, episode_id.encode("utf-8"), hashlib.sha256).hexdigest()[:16]
