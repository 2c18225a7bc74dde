"""The reference MiniGrid 3.2 environment for a Maze level, as the ACCEL agent was trained on (SPEC: the Maze).

Evaluations use the faster :class:`~dsage_ray.domains.maze.simulator.BatchedMazeSimulator`; this
class is the ground truth the simulator is tested against, and what ``gymnasium.make`` returns.
:func:`minigrid_evaluate` is :func:`~dsage_ray.domains.maze.evaluate.evaluate`'s protocol played on
it, one env per episode: the slow reference a new agent's numbers can be cross-checked against.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import gymnasium
import numpy as np
from minigrid.core.grid import Grid
from minigrid.core.mission import MissionSpace
from minigrid.core.world_object import Goal, Wall
from minigrid.minigrid_env import MiniGridEnv

from dsage_ray.domains.maze.level import MazeLevel

if TYPE_CHECKING:
    from dsage_ray.agents.base import Agent

#: The gymnasium id; registered when :mod:`dsage_ray.domains.maze` is imported.
ENV_ID = "dsage_ray/Maze-v0"
MISSION = "get to the green goal square"


def _mission() -> str:
    return MISSION


class MazeEnv(MiniGridEnv):
    """One Maze level as a MiniGrid environment.

    The grid is the level's interior plus a border wall; the agent starts on the level's start
    with a heading drawn from the env's ``np_random``, the goal object sits on the level's goal.
    Seven actions (0 left, 1 right, 2 forward, 3–6 no-ops that still use a step); reward
    ``1 − 0.9·steps/max_steps`` on entering the goal.

    Args:
        level: A valid level.
        see_through_walls: False applies MiniGrid's occlusion mask to observations.
        agent_view_size: Side of the egocentric view (odd, ≥ 3).
        max_steps: Episode step limit; default ``level.max_steps`` (``2·(H+2)·(W+2)``).
        render_mode: ``None``, ``"rgb_array"`` or ``"human"``.

    Raises:
        ValueError: The level is invalid (no connected start and goal).
    """

    def __init__(
        self,
        level: MazeLevel,
        *,
        see_through_walls: bool = True,
        agent_view_size: int = 5,
        max_steps: int | None = None,
        render_mode: str | None = None,
    ):
        if not level.valid:
            raise ValueError("MazeEnv needs a valid level (a start and a goal connected to each other)")
        self.level = level
        super().__init__(
            mission_space=MissionSpace(mission_func=_mission),
            width=level.width + 2,
            height=level.height + 2,
            max_steps=int(max_steps if max_steps is not None else level.max_steps),
            see_through_walls=see_through_walls,
            agent_view_size=agent_view_size,
            render_mode=render_mode,
        )

    def _gen_grid(self, width: int, height: int) -> None:
        self.grid = Grid(width, height)
        self.grid.wall_rect(0, 0, width, height)
        for row, col in zip(*self.level.walls.nonzero()):
            self.grid.set(int(col) + 1, int(row) + 1, Wall())
        goal_row, goal_col = self.level.goal
        self.put_obj(Goal(), goal_col + 1, goal_row + 1)
        start_row, start_col = self.level.start
        self.agent_pos = (start_col + 1, start_row + 1)
        self.agent_dir = self._rand_int(0, 4)
        self.mission = MISSION


def register_env() -> None:
    """Registers :data:`ENV_ID` with gymnasium (idempotent)."""
    if ENV_ID not in gymnasium.registry:
        gymnasium.register(id=ENV_ID, entry_point="dsage_ray.domains.maze.env:MazeEnv")


def minigrid_evaluate(level: MazeLevel, agent: "Agent", *, episodes: int, seed: int,
                      see_through_walls: bool = True) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``evaluate()``'s protocol and random-number use, stepping one :class:`MazeEnv` per episode.

    Same seed, same agent: the same actions and outcomes as
    :func:`~dsage_ray.domains.maze.evaluate.evaluate`, at MiniGrid's speed.

    Returns:
        ``(lengths, successes, occupancy)``: steps and success per episode, and the mean visits per
        interior cell per episode (counted before each step, as ``evaluate`` does).
    """
    rng = np.random.default_rng(seed)
    envs = [MazeEnv(level, see_through_walls=see_through_walls) for _ in range(episodes)]
    observations = []
    for env, heading in zip(envs, rng.integers(0, 4, size=episodes)):
        env.reset(seed=0)
        env.agent_dir = int(heading)  # evaluate() draws the headings from its rng; MazeEnv from its own
        observations.append(env.gen_obs())
    state = agent.initial_state(episodes)
    lengths = np.zeros(episodes, dtype=np.int64)
    successes = np.zeros(episodes, dtype=bool)
    occupancy = np.zeros(level.walls.shape)
    running = np.arange(episodes)
    while running.size:
        obs = {"image": np.stack([observations[e]["image"] for e in running]),
               "direction": np.array([observations[e]["direction"] for e in running], dtype=np.int64)}
        actions, state = agent.act(obs, state, rng)
        alive = []
        for k, e in enumerate(running):
            x, y = envs[e].agent_pos
            occupancy[y - 1, x - 1] += 1
            observations[e], _, terminated, truncated, _ = envs[e].step(int(actions[k]))
            if terminated or truncated:
                lengths[e], successes[e] = envs[e].step_count, terminated
            else:
                alive.append(k)
        alive = np.array(alive, dtype=np.int64)
        state = agent.select_state(state, alive)
        running = running[alive]
    return lengths, successes, occupancy / max(episodes, 1)
