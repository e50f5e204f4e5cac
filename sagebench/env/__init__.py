"""`sagebench.env`: the benchmark as a gymnasium environment (one episode) and its vectorised form (several).

Both only compose the closed-loop simulator (sagebench.navsim): spaces, reset and step in gymnasium's terms.
Importing this package registers NavEnv as ENV_ID, so training code can build it the field's way:
`gymnasium.make("sagebench.env:sagebench/Nav-v0", run_dir=..., config={...})` (the module prefix imports us).
"""

import gymnasium

from sagebench.env.gym_env import NavEnv, VectorNavEnv, action_space, observation_space

ENV_ID = "sagebench/Nav-v0"
if ENV_ID not in gymnasium.registry:  # the step limit and nogoal's budget are the env's own: no TimeLimit wrapper
    gymnasium.register(id=ENV_ID, entry_point="sagebench.env.gym_env:NavEnv")

__all__ = ["ENV_ID", "NavEnv", "VectorNavEnv", "action_space", "observation_space"]
