"""``random``: uniformly random actions in any Discrete, Box, MultiDiscrete or MultiBinary action space."""

from __future__ import annotations

from typing import Any

import gymnasium
import numpy as np
from gymnasium import spaces

from dsage_ray.agents.base import Agent, AgentState
from dsage_ray.agents.spaces import batch_size, finish_actions


class UniformRandomAgent(Agent):
    """Uniformly random actions (Box: uniform within finite bounds, standard normal where unbounded).

    Args:
        action_space: The environment's action space.
    """

    def __init__(self, *, action_space: gymnasium.Space) -> None:
        self.action_space = action_space

    def initial_state(self, batch_size: int) -> AgentState:
        return None

    def act(self, obs: Any, state: AgentState, rng: np.random.Generator) -> tuple[np.ndarray, AgentState]:
        n = batch_size(obs)
        space = self.action_space
        size = (n, *space.shape)
        if isinstance(space, spaces.Discrete):
            actions = space.start + rng.integers(0, space.n, size=n)
        elif isinstance(space, spaces.MultiDiscrete):
            actions = space.start + rng.integers(0, space.nvec, size=size)
        elif isinstance(space, spaces.MultiBinary):
            actions = rng.integers(0, 2, size=size)
        else:
            bounded = np.isfinite(space.low) & np.isfinite(space.high)
            width = np.where(bounded, space.high - space.low, 0.0)
            uniform = np.where(bounded, space.low, 0.0) + rng.random(size) * width
            actions = np.where(bounded, uniform, rng.standard_normal(size))
        return finish_actions(actions, space), None
