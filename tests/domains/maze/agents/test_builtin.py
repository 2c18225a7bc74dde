"""The checkpoint-free agents: a uniform random policy and a deterministic right-hand wall follower."""

from __future__ import annotations

import numpy as np
import pytest

from dsage_ray.domains.maze.agents import load_maze_agent
from dsage_ray.domains.maze.agents.builtin import RandomAgent, WallFollowerAgent
from dsage_ray.domains.maze import MazeLevel, evaluate
from tests.domains.maze.agents.mazes import labyrinth13, open_maze, perfect_maze


def test_builtin_specs_load_and_record_spec():
    assert isinstance(load_maze_agent("builtin:random"), RandomAgent)
    agent = load_maze_agent("builtin:wall_follower")
    assert isinstance(agent, WallFollowerAgent) and agent.spec == "builtin:wall_follower"
    assert load_maze_agent("builtin:random?actions=7").num_actions == 7


def test_random_agent_range_and_reproducibility():
    obs = {"image": np.zeros((500, 5, 5, 3), np.uint8), "direction": np.zeros(500, np.int64)}
    three, seven = load_maze_agent("builtin:random"), load_maze_agent("builtin:random?actions=7")
    a, _ = three.act(obs, three.initial_state(500), np.random.default_rng(0))
    assert a.dtype == np.int64 and set(a.tolist()) == {0, 1, 2}
    b, _ = seven.act(obs, None, np.random.default_rng(0))
    assert set(b.tolist()) == set(range(7))
    np.testing.assert_array_equal(a, three.act(obs, None, np.random.default_rng(0))[0])


SOLVABLE = [
    ("labyrinth13", labyrinth13),
    *[(f"perfect13_{s}", lambda s=s: perfect_maze(13, s)) for s in range(3)],
    *[(f"perfect16_{s}", lambda s=s: perfect_maze(16, s)) for s in range(3)],
    ("corridor", lambda: MazeLevel.from_bitmap(np.array([[0, 0, 0, 0], [1, 1, 1, 0], [0, 0, 0, 0]]))),
    ("empty16", lambda: MazeLevel.from_bitmap(np.zeros((16, 16)))),
]


@pytest.mark.parametrize("see_through_walls", [True, False])
@pytest.mark.parametrize("name, make", SOLVABLE, ids=[name for name, _ in SOLVABLE])
def test_wall_follower_solves_simply_connected_mazes(name, make, see_through_walls):
    result = evaluate(make(), load_maze_agent("builtin:wall_follower"), episodes=8, seed=0,
                      see_through_walls=see_through_walls)
    assert result.success_rate == 1.0, f"{name}: lengths {result.episode_lengths}"
    assert (result.episode_lengths >= result.optimal_path_length).all()


def test_wall_follower_is_deterministic_and_ignores_the_rng():
    level, agent = open_maze(16, 0.2, 1), load_maze_agent("builtin:wall_follower")
    first = evaluate(level, agent, episodes=12, seed=3)
    again = evaluate(level, agent, episodes=12, seed=3)
    np.testing.assert_array_equal(first.episode_lengths, again.episode_lengths)
    assert first.success_rate == 1.0


def test_wall_follower_rules_on_hand_made_views():
    agent = load_maze_agent("builtin:wall_follower")
    wall, empty, goal = (2, 5, 0), (1, 0, 0), (8, 1, 0)

    def view(ahead, left, right):
        image = np.zeros((5, 5, 3), np.uint8)
        image[:, :] = empty
        image[2, 3], image[1, 4], image[3, 4] = ahead, left, right
        return image

    images = np.stack([
        view(empty, wall, wall),  # seeking: open ahead -> forward
        view(wall, empty, empty),  # seeking: blocked -> turn left, start following
        view(empty, wall, empty),  # following, right open -> turn right
        view(empty, wall, empty),  # just turned right -> forward, not another right
        view(wall, empty, wall),  # following, blocked ahead and right -> left
        view(wall, goal, wall),  # goal beside -> turn toward it
    ])
    state = np.array([0, 0, 1, 2, 1, 1], np.int8)
    actions, new_state = agent.act({"image": images, "direction": np.zeros(6, np.int64)}, state, None)
    np.testing.assert_array_equal(actions, [2, 0, 1, 2, 0, 0])
    np.testing.assert_array_equal(new_state, [0, 1, 2, 1, 1, 1])
    # Episode bookkeeping on numpy state.
    np.testing.assert_array_equal(agent.select_state(new_state, np.array([2, 5])), [2, 1])
