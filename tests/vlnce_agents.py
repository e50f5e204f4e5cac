"""Agents written the way VLN-CE's vlnce_baselines writes its non-learning ones (habitat.core.agent.Agent's
reset() and act(observations) -> {"action": HabitatSimActions.X}), for the adapter's tests. habitat is not
installed here: its action ids are VLN-CE's 0 STOP, 1 MOVE_FORWARD, 2 TURN_LEFT, 3 TURN_RIGHT."""

from __future__ import annotations

import numpy as np


class HabitatSimActions:
    STOP = 0
    MOVE_FORWARD = 1
    TURN_LEFT = 2
    TURN_RIGHT = 3


class DepthAgent:
    """Reads the instruction's tokens for its step budget and depth to steer: turns left while something is
    within 0.6 m ahead (depth is normalised over 0-10 m), else moves forward; stops when the budget is spent."""

    def __init__(self):
        self.reset()

    def reset(self):
        self.budget = None
        self.checked = []

    def act(self, observations):
        rgb, depth = observations["rgb"], observations["depth"]
        tokens = observations["instruction"]["tokens"]
        self.checked.append((rgb.shape, rgb.dtype, depth.shape, depth.dtype, len(tokens)))
        if self.budget is None:
            self.budget = 4 + int(np.count_nonzero(tokens)) % 5
        if self.budget == 0:
            return {"action": HabitatSimActions.STOP}
        self.budget -= 1
        h, w, _ = depth.shape
        ahead = depth[h // 2, w // 3: 2 * w // 3, 0].min() * 10.0
        if ahead < 0.6:
            return {"action": HabitatSimActions.TURN_LEFT}
        return {"action": HabitatSimActions.MOVE_FORWARD}


ONE_AGENT = DepthAgent()  # a single agent object: it runs one episode at a time


class GoalAgent:
    """An ImageNav agent of habitat's kind: keeps the `imagegoal` it is shown (in `seen`, shared by every instance),
    then stops."""

    seen: list[np.ndarray] = []

    def reset(self):
        pass

    def act(self, observations):
        GoalAgent.seen.append(np.array(observations["imagegoal"]))
        return {"action": HabitatSimActions.STOP}


class SensorAgent:
    """A PointNav / ObjectNav agent of habitat's kind: keeps the observation dict it is shown first (in `seen`,
    shared by every instance), then stops. Its ObjectNav category ids are habitat's dataset map."""

    category_to_task_category_id = {"bed": 3, "cabinet": 0, "door": 4, "sofa": 1, "table": 2}
    seen: list[dict] = []

    def reset(self):
        pass

    def act(self, observations):
        SensorAgent.seen.append({k: np.array(v) for k, v in observations.items() if k not in ("rgb", "depth")})
        return {"action": HabitatSimActions.STOP}


class MaplessAgent(SensorAgent):
    """A SensorAgent without habitat's category map: it cannot be told an ObjectNav goal."""

    category_to_task_category_id = None
