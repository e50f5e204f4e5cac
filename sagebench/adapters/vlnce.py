"""VLN-CE's conventions in sagebench's closed loop: the `vlnce` preset (the R2R task's success distance, body and
camera) and an adapter that runs an object with habitat's `Agent` interface unchanged.

VLN-CE's R2R task (jacobkrantz/VLN-CE habitat_extensions/config/vlnce_task.yaml over habitat-lab 0.1.7's
defaults): success within 3.0 m of the goal, an agent of radius 0.1 m and height 1.5 m whose RGB and depth
sensors sit 1.25 m up with a 90-degree field of view, RGB 224x224, depth 256x256 normalised over 0-10 m,
MOVE_FORWARD 0.25 m, TURN_LEFT / TURN_RIGHT 15 degrees, 500 steps. The preset sets those that sagebench's
defaults do not already share (sagebench: each episode's goal_radius, 1 m by default; radius 0.2 m, height
1.2 m, camera 1.2 m; the custom profile); `preset_differences` lists them for the user.
"""

from __future__ import annotations

from sagebench.config import AgentConfig
from sagebench.navsim.simulator import EnvConfig

PRESETS = ("vlnce",)
VLNCE_SUCCESS_DISTANCE = 3.0  # m, vlnce_task.yaml TASK.SUCCESS.SUCCESS_DISTANCE
VLNCE_AGENT = AgentConfig(radius=0.1, height=1.5, camera_height=1.25, hfov_deg=90.0)  # habitat-lab 0.1.7 AGENT_0 + sensors


def preset_env(name: str) -> dict:
    """The EnvConfig fields a preset sets (a dict to merge under the options given)."""
    if name != "vlnce":
        raise ValueError(f"{name!r} is not a preset (one of {', '.join(PRESETS)})")
    return {"profile": "vlnce", "agent": VLNCE_AGENT.model_dump(), "success_distance": VLNCE_SUCCESS_DISTANCE,
            "max_steps": 500, "actions": {"forward_step": 0.25, "turn_deg": 15.0}}


def preset_differences(env: EnvConfig, default: EnvConfig) -> list[str]:
    """What an env config (EnvConfig) sets differently from sagebench's default one: 'name value (default d)'."""
    out = []
    if env.success_distance != default.success_distance:
        out.append(f"success distance {env.success_distance:g} m (default: each episode's goal_radius)")
    for name, label in (("radius", "agent radius"), ("height", "agent height"), ("camera_height", "camera height"),
                        ("hfov_deg", "hfov")):
        a, b = getattr(env.agent, name), getattr(default.agent, name)
        if a != b:
            out.append(f"{label} {a:g}{'' if name == 'hfov_deg' else ' m'} (default {b:g})")
    if env.profile != default.profile:
        out.append(f"observations: the {env.profile} profile (default {default.profile})")
    if env.max_steps != default.max_steps:
        out.append(f"max steps {env.max_steps} (default {default.max_steps})")
    return out
