"""The gymnasium env RLlib trains maze agents on: a fresh random valid maze every episode.

Research code of ``experiments/train_maze_agent.py``, kept beside it (not in the dsage_ray package): the script
imports it from its own folder, and RLlib steps it in the driver process (no remote env runner).

The mazes come from :func:`dsage_ray.domains.maze.generator.random_valid_level`, the same distribution
the agent benchmark evaluates. ``RandomMazeEnv`` wraps the project's :class:`~dsage_ray.domains.maze.env.MazeEnv`
(so the dynamics and observations are the ones the evaluator's simulator is tested against) and drops the
constant mission string from the observation. Its curriculum knob ``difficulty`` in ``[0, 1]`` caps how far
the goal is from the start: below 1 the goal is a random reachable cell at most ``3 + difficulty·(max_goal_distance -
3)`` moves away; at 1 it is the furthest pair, the evaluation setting. The training script
(``experiments/train_maze_agent.py``) raises it as training proceeds (``env.set_attr("difficulty", ...)`` on
the vector env).

**Mixing in audit levels.** ``levels`` (layout texts, e.g. an audit collection's level files) and
``level_share`` make a share of the episodes replay those levels instead of a fresh random maze: at every
reset, with probability ``level_share`` (drawn from the env's seeded ``np_random``), a level picked
uniformly from ``levels``. The curriculum applies to them as to random mazes (below difficulty 1 their
goal moves closer); at 1 they are played exactly as the audit evaluated them. ``info["source_level"]`` is
the index of the replayed level, -1 for a random maze. Without ``levels`` no extra random number is drawn,
so training is the same as before for the same seed. ``experiments/train_maze_agent.py
--train-on-collection DIR`` reads the collection and passes its levels here.
"""

from __future__ import annotations

from typing import Any, Sequence

import gymnasium as gym
import numpy as np

from dsage_ray.domains.maze.agents.constants import ACTION_SPACE, OBSERVATION_SPACE
from dsage_ray.domains.maze.env import MazeEnv
from dsage_ray.domains.maze.generator import DEFAULT_DENSITY_RANGE, random_valid_level
from dsage_ray.domains.maze.layout import parse_layout
from dsage_ray.domains.maze.level import MazeLevel, path_distances
from dsage_ray.errors import InputError


def with_near_goal(level: MazeLevel, max_distance: int, rng: np.random.Generator) -> MazeLevel:
    """``level`` with its goal moved to a random reachable cell at most ``max_distance`` moves from the start.

    Returns ``level`` itself when no other cell is that close.
    """
    distance = path_distances(level.walls, level.start)
    candidates = np.flatnonzero((distance > 0) & (distance <= max_distance))
    if candidates.size == 0:
        return level
    goal = divmod(int(rng.choice(candidates)), level.width)
    return MazeLevel.from_bitmap(level.walls, start=level.start, goal=goal)


class RandomMazeEnv(gym.Env):
    """A new random valid maze every episode; MiniGrid's Maze observation minus the mission string.

    Args:
        height: Interior rows.
        width: Interior columns.
        density_range: Wall probability range (see :func:`random_valid_level`).
        difficulty: Curriculum position in ``[0, 1]`` (module docstring); settable between episodes.
        max_goal_distance: Goal distance cap just below difficulty 1.
        see_through_walls: MiniGrid's observation setting (the evaluator's default is True).
        levels: Layout texts (:mod:`~dsage_ray.domains.maze.layout`) of fixed levels to mix in, all
            ``height`` × ``width``; e.g. an audit collection's level files.
        level_share: Probability in ``[0, 1]`` that an episode replays one of ``levels``.

    Raises:
        InputError: A malformed layout in ``levels``, one of another size, or ``level_share`` outside
            ``[0, 1]``.
    """

    metadata = {"render_modes": []}

    def __init__(
        self,
        *,
        height: int = 16,
        width: int = 16,
        density_range: tuple[float, float] = DEFAULT_DENSITY_RANGE,
        difficulty: float = 1.0,
        max_goal_distance: int = 60,
        see_through_walls: bool = True,
        levels: Sequence[str] = (),
        level_share: float = 0.0,
    ) -> None:
        self.height, self.width = height, width
        self.density_range = tuple(density_range)
        self.difficulty = float(difficulty)
        self.max_goal_distance = max_goal_distance
        self.levels = parse_levels(levels, height=height, width=width)
        if not 0.0 <= float(level_share) <= 1.0:
            raise InputError(f"level share {level_share} is not a probability in [0, 1]")
        self.level_share = float(level_share) if self.levels else 0.0
        #: Index into ``levels`` of the current episode's level; -1 for a random maze.
        self.source_level = -1
        self.observation_space = OBSERVATION_SPACE
        self.action_space = ACTION_SPACE
        self._maze = MazeEnv(random_valid_level(np.random.default_rng(0), height=height, width=width),
                             see_through_walls=see_through_walls)

    def _next_level(self) -> MazeLevel:
        self.source_level = -1
        if self.level_share > 0.0 and self.np_random.random() < self.level_share:
            self.source_level = int(self.np_random.integers(len(self.levels)))
            level = self.levels[self.source_level]
        else:
            level = random_valid_level(self.np_random, height=self.height, width=self.width,
                                       density_range=self.density_range)
        if self.difficulty < 1.0:
            cap = 3 + int(self.difficulty * (self.max_goal_distance - 3))
            level = with_near_goal(level, cap, self.np_random)
        return level

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        super().reset(seed=seed)
        # Same grid size every episode, so swapping the level in is all MiniGrid's reset needs.
        self._maze.level = self._next_level()
        obs, info = self._maze.reset(seed=int(self.np_random.integers(2**31)))
        info["optimal_path_length"] = self._maze.level.optimal_path_length
        info["source_level"] = self.source_level
        return _strip(obs), info

    def step(self, action):
        obs, reward, terminated, truncated, info = self._maze.step(int(action))
        return _strip(obs), float(reward), terminated, truncated, info


def parse_levels(levels: Sequence[str], *, height: int = 16, width: int = 16) -> list[MazeLevel]:
    """Layout texts as levels of the training env's size; InputError naming the level that is not one."""
    if isinstance(levels, str):
        raise InputError("levels must be a sequence of layout texts, not one string")
    parsed = []
    for i, text in enumerate(levels):
        level = parse_layout(text, source=f"level {i}")
        if (level.height, level.width) != (height, width):
            raise InputError(f"level {i} is {level.height}x{level.width}; the training mazes are {height}x{width}")
        parsed.append(level)
    return parsed


def _strip(obs: dict[str, Any]) -> dict[str, Any]:
    return {"direction": int(obs["direction"]), "image": obs["image"]}


def make_random_maze_env(env_config: dict[str, Any] | None = None) -> RandomMazeEnv:
    """RLlib env creator: ``config.environment(make_random_maze_env, env_config={...})`` keys = constructor's."""
    config = {k: v for k, v in dict(env_config or {}).items() if k != "num_envs"}
    return RandomMazeEnv(**config)
