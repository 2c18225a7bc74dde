"""Shared helpers for the Maze tests: a test-local agent and a random-maze generator."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from dsage_ray.agents.base import Agent
from dsage_ray.domains.maze.agents.constants import NUM_ACTIONS
from dsage_ray.domains.maze.level import MazeLevel

DATA = Path(__file__).parent / "data"


class UniformRandomAgent(Agent):
    """Uniformly random actions from the rng it is handed; records the batch size of every call."""

    spec = "test:uniform_random"

    def __init__(self, num_actions: int = NUM_ACTIONS):
        self.num_actions = num_actions
        self.batch_sizes: list[int] = []

    def initial_state(self, batch_size: int):
        return np.zeros(batch_size, dtype=np.int64)  # a step counter, to exercise select_state

    def act(self, obs, state, rng):
        n = len(obs["direction"])
        assert obs["image"].shape == (n, 5, 5, 3) and len(state) == n
        self.batch_sizes.append(n)
        return rng.integers(0, self.num_actions, size=n), state + 1


def random_level(rng: np.random.Generator, *, max_side: int = 12, density: float = 0.3) -> MazeLevel:
    """A random valid level of random rectangular size."""
    while True:
        height, width = rng.integers(2, max_side + 1, size=2)
        level = MazeLevel.from_bitmap(rng.random((height, width)) < density)
        if level.valid:
            return level


@pytest.fixture
def agent() -> UniformRandomAgent:
    return UniformRandomAgent()
