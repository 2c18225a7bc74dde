import gymnasium
import numpy as np
import pytest

import dsage_ray.domains.maze  # noqa: F401  (registers the env)
from dsage_ray.domains.maze.env import ENV_ID, MazeEnv
from dsage_ray.domains.maze.layout import load_layout
from dsage_ray.domains.maze.level import MazeLevel

from .conftest import DATA


def test_gymnasium_make_builds_the_level():
    level = load_layout(DATA / "corridor_sg.txt")
    env = gymnasium.make(ENV_ID, level=level)
    obs, _ = env.reset(seed=3)
    inner = env.unwrapped
    assert isinstance(inner, MazeEnv)
    assert (inner.width, inner.height, inner.max_steps) == (7, 5, 70)
    assert tuple(inner.agent_pos) == (1, 1) and inner.grid.get(1, 3).type == "goal"
    assert inner.grid.get(1, 2).type == "wall" and inner.grid.get(0, 0).type == "wall"
    assert obs["image"].shape == (5, 5, 3) and env.action_space.n == 7
    assert obs["image"][2, 4].tolist() == [1, 0, 0]  # the agent's own cell reads as empty
    env.close()


def test_defaults_follow_spec():
    env = MazeEnv(MazeLevel.from_bitmap(np.zeros((16, 16))))
    assert env.see_through_walls and env.agent_view_size == 5 and env.max_steps == 648


def test_initial_heading_comes_from_np_random():
    env = MazeEnv(load_layout(DATA / "small.txt"))
    headings = {int(env.reset(seed=seed)[0]["direction"]) for seed in range(30)}
    assert headings == {0, 1, 2, 3}
    assert env.reset(seed=5)[0]["direction"] == env.reset(seed=5)[0]["direction"]


def test_reward_on_reaching_goal():
    # 1x2 corridor can't exist (min 2x2); use a 2x2 with one wall: start (0,0), goal (1,1) via (0,1).
    level = MazeLevel.from_bitmap(np.array([[0, 0], [1, 0]]))
    env = MazeEnv(level, max_steps=20)
    env.reset(seed=0)
    env.unwrapped.agent_dir = 0  # face right (+x)
    _, r, term, trunc, _ = env.step(2)
    assert (r, term) == (0, False)
    env.step(1)  # face down
    _, r, term, trunc, _ = env.step(2)
    assert term and not trunc and r == pytest.approx(1 - 0.9 * 3 / 20)


def test_invalid_level_rejected():
    with pytest.raises(ValueError, match="valid level"):
        MazeEnv(MazeLevel.from_bitmap(np.ones((3, 3))))
