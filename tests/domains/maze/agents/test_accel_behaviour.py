"""The real ACCEL checkpoint in our Maze environment behaves as the paper reports: it reaches the goal.

If these fail, the environment or observation differs from the one the agent was trained in (see-through
walls, /10 scaling, the (3, x, y) transpose, heading encoding) — fix the difference, don't loosen the bound.
The negative controls show the checks are sensitive to exactly those differences.
"""

from __future__ import annotations

import numpy as np
import pytest

from dsage_ray.agents import Agent
from dsage_ray.domains.maze.agents import load_maze_agent
from dsage_ray.domains.maze import evaluate
from tests.domains.maze.agents.conftest import ACCEL_SPEC
from tests.domains.maze.agents.mazes import labyrinth13, open_maze, perfect_maze


@pytest.fixture(scope="module")
def accel():
    return load_maze_agent(ACCEL_SPEC)


class _SwappedView(Agent):
    """Feeds the agent its view with x and y exchanged: the orientation mistake the transpose guards against."""

    def __init__(self, inner: Agent) -> None:
        self.inner = inner

    def initial_state(self, batch_size):
        return self.inner.initial_state(batch_size)

    def select_state(self, state, index):
        return self.inner.select_state(state, index)

    def act(self, obs, state, rng):
        return self.inner.act({"image": obs["image"].transpose(0, 2, 1, 3), "direction": obs["direction"]}, state, rng)


@pytest.mark.parametrize("name, make", [("labyrinth13", labyrinth13), ("open13", lambda: open_maze(13, 0.1, 0))])
def test_accel_reaches_the_goal(accel, name, make):
    result = evaluate(make(), accel, episodes=50, seed=0)
    assert result.success_rate >= 0.9, f"{name}: success {result.success_rate:.2f}, lengths {result.episode_lengths}"


def test_wrong_orientation_or_occlusion_makes_it_wander(accel):
    level = labyrinth13()
    assert evaluate(level, _SwappedView(accel), episodes=20, seed=0).success_rate <= 0.2
    assert evaluate(level, accel, episodes=20, seed=0, see_through_walls=False).success_rate <= 0.2


def test_accel_is_reproducible(accel):
    level = open_maze(13, 0.1, 0)
    a, b = (evaluate(level, accel, episodes=10, seed=5) for _ in range(2))
    np.testing.assert_array_equal(a.episode_lengths, b.episode_lengths)


@pytest.mark.slow
@pytest.mark.parametrize("spec_suffix", ["", "?heading_quirk=1"])
def test_accel_on_random_perfect_mazes(spec_suffix):
    agent = load_maze_agent(f"{ACCEL_SPEC}{spec_suffix}")
    rates = [evaluate(perfect_maze(13, seed), agent, episodes=50, seed=0).success_rate for seed in range(3)]
    assert np.mean(rates) >= 0.85, rates
