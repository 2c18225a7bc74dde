"""The RLlib training env (``experiments/maze_training_env.py``): curriculum goals and the observation it returns."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from dsage_ray.domains.maze.agents.constants import ACTION_SPACE, OBSERVATION_SPACE
from dsage_ray.domains.maze.generator import random_valid_levels
from dsage_ray.domains.maze.level import MazeLevel, path_distances

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "experiments"))

from maze_training_env import RandomMazeEnv, make_random_maze_env, with_near_goal  # noqa: E402


@pytest.mark.parametrize("max_distance", [1, 3, 10])
def test_near_goal_is_reachable_within_the_cap(max_distance):
    for seed, level in enumerate(random_valid_levels(10, seed=4)):
        near = with_near_goal(level, max_distance, np.random.default_rng(seed))
        assert near.start == level.start and near.valid
        assert 0 < path_distances(level.walls, level.start)[near.goal] <= max_distance
        assert near.optimal_path_length <= max_distance


def test_near_goal_keeps_a_level_without_a_close_cell():
    corridor = np.ones((2, 5), dtype=bool)
    corridor[0] = False
    level = MazeLevel.from_bitmap(corridor, start=(0, 0), goal=(0, 4))
    lonely = MazeLevel.from_bitmap(np.array([[0, 1], [1, 0]]), start=(0, 0), goal=(1, 1))  # goal unreachable
    assert with_near_goal(lonely, 3, np.random.default_rng(0)) is lonely
    assert with_near_goal(level, 2, np.random.default_rng(0)).goal in {(0, 1), (0, 2)}


def test_env_observations_fit_the_policy_spaces_and_difficulty_caps_the_goal():
    env = make_random_maze_env({"difficulty": 0.0, "num_envs": 8, "max_goal_distance": 20})
    assert isinstance(env, RandomMazeEnv)
    assert env.observation_space == OBSERVATION_SPACE and env.action_space == ACTION_SPACE
    lengths = []
    for seed in range(5):
        obs, info = env.reset(seed=seed)
        assert OBSERVATION_SPACE.contains(obs)
        lengths.append(info["optimal_path_length"])
        obs, reward, terminated, truncated, _ = env.step(2)
        assert OBSERVATION_SPACE.contains(obs) and isinstance(reward, float)
    assert max(lengths) <= 3  # difficulty 0: the goal at most 3 moves away
    env.difficulty = 1.0
    _, info = env.reset(seed=0)
    assert info["optimal_path_length"] > 3  # difficulty 1: the furthest pair
