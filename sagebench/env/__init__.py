"""`sagebench.env`: the benchmark as a gymnasium environment (one episode) and its vectorised form (several).

Both only compose the closed-loop simulator (sagebench.navsim): spaces, reset and step in gymnasium's terms.
"""

from sagebench.env.gym_env import NavEnv, VectorNavEnv, action_space, observation_space

__all__ = ["NavEnv", "VectorNavEnv", "action_space", "observation_space"]
