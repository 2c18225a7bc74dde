"""Runs an agent on a level for many episodes at once and summarises its behaviour (SPEC: the Maze)."""

from __future__ import annotations

import dataclasses
import json
from typing import Any, Sequence

import numpy as np

from dsage_ray.agents.base import Agent
from dsage_ray.domains.maze.level import Cell, MazeLevel
from dsage_ray.domains.maze.simulator import BatchedMazeSimulator
from dsage_ray.memory import require_memory


@dataclasses.dataclass
class MazeEvaluation:
    """What ``episodes`` episodes of one agent on one level did.

    Attributes:
        episodes: Episodes run (0 on an invalid level: the agent is not run).
        valid: Whether the level has a connected start and goal.
        num_walls: Wall cells in the level.
        optimal_path_length: Shortest start→goal path in forward moves (0 when invalid).
        max_steps: The episode step limit.
        success_rate: Fraction of episodes that reached the goal.
        mean_path_length: Mean steps per episode, a failed episode counting ``max_steps``; 0 when invalid.
        episode_lengths: ``(episodes,)`` int64 steps taken per episode.
        successes: ``(episodes,)`` bool, True where the episode reached the goal.
        occupancy: ``(H, W)`` float32 in interior coordinates: visits recorded before each step,
            summed over episodes, divided by ``episodes`` (the start is counted, the goal never).
        explored_fraction: Mean over episodes of the fraction of reachable cells the agent
            occupied at some point (the goal counts when reached).
        repeated_visits: Mean over episodes of the steps begun on a cell already occupied earlier
            in the episode (turning in place counts); in ``[0, max_steps]``.
        start: Interior ``(row, col)`` of the start, or None.
        goal: Interior ``(row, col)`` of the goal, or None.
    """

    episodes: int
    valid: bool
    num_walls: int
    optimal_path_length: int
    max_steps: int
    success_rate: float
    mean_path_length: float
    episode_lengths: np.ndarray
    successes: np.ndarray
    occupancy: np.ndarray
    explored_fraction: float
    repeated_visits: float
    start: Cell | None
    goal: Cell | None

    def to_dict(self, *, occupancy: bool = False) -> dict[str, Any]:
        """JSON-serialisable summary; ``occupancy=True`` includes the occupancy grid as nested lists."""
        out = {
            field.name: getattr(self, field.name)
            for field in dataclasses.fields(self)
            if field.name != "occupancy" or occupancy
        }
        out["episode_lengths"] = self.episode_lengths.tolist()
        out["successes"] = self.successes.tolist()
        out["start"] = list(self.start) if self.start is not None else None
        out["goal"] = list(self.goal) if self.goal is not None else None
        if occupancy:
            out["occupancy"] = self.occupancy.tolist()
        return out

    def to_json(self, *, occupancy: bool = False) -> str:
        """:meth:`to_dict` as one line of JSON."""
        return json.dumps(self.to_dict(occupancy=occupancy))


def evaluate(
    level: MazeLevel,
    agent: Agent | None,
    *,
    episodes: int = 50,
    seed: int = 0,
    see_through_walls: bool = True,
) -> MazeEvaluation:
    """Runs ``episodes`` episodes of ``agent`` on ``level`` in one batch.

    Policy inference is batched across the running episodes; finished episodes leave the batch.
    Every random draw (initial headings, then the ``rng`` handed to ``agent.act``) comes from
    ``np.random.default_rng(seed)``, so the result is a function of ``(level, agent, seed)``.

    Args:
        level: The level; an invalid one returns at once without running the agent.
        agent: A batched policy; may be None for an invalid level (it is not used).
        episodes: Episodes to run.
        seed: Seeds all randomness.
        see_through_walls: MiniGrid's observation setting (the ACCEL agent was trained with True).
    """
    return evaluate_levels([level], agent, episodes=episodes, seed=seed, see_through_walls=see_through_walls)[0]


def evaluate_levels(
    levels: Sequence[MazeLevel],
    agent: Agent | None,
    *,
    episodes: int = 50,
    seed: int = 0,
    see_through_walls: bool = True,
) -> list[MazeEvaluation]:
    """Runs ``episodes`` episodes of ``agent`` on each of ``levels`` (one size), all in one batch.

    One policy step serves every running episode of every level, so many short evaluations (a few episodes
    each) cost about their episodes' steps, not one small batch per level. The draws come from one
    ``np.random.default_rng(seed)`` for the whole batch: a level's result depends on the levels beside it,
    and with a single level it is exactly :func:`evaluate`'s.

    Args:
        levels: The levels; invalid ones get :func:`evaluate`'s invalid result and are not run.
        agent: A batched policy; may be None when no level is valid.
        episodes: Episodes per level.
        seed: Seeds all randomness.
        see_through_walls: MiniGrid's observation setting.
    """
    if episodes < 1:
        raise ValueError(f"episodes must be positive, got {episodes}")
    valid = [level for level in levels if level.valid]
    runs = iter(_run_levels(valid, agent, episodes=episodes, seed=seed, see_through_walls=see_through_walls)
                if valid else [])
    return [next(runs) if level.valid else _not_run(level) for level in levels]


#: Memory one running episode takes beside its visit counts: its observation, simulator state and its share of
#: the policy's activations (measured: 28 KB for ACCEL's LSTM policy, 14 KB for the shipped PPO; rounded up).
EPISODE_BYTES = 32_000


def check_episode_memory(episodes: int, shape: tuple[int, int]) -> None:
    """Raises ResourceError when ``episodes`` side by side on levels of ``shape`` would not fit in memory."""
    height, width = shape
    per_episode = EPISODE_BYTES + 4 * (height + 2) * (width + 2)
    require_memory(episodes * per_episode, what=f"{episodes:,} episodes side by side on {height}×{width} mazes",
                   key="maze.episodes (--episodes)")


def _not_run(level: MazeLevel) -> MazeEvaluation:
    return MazeEvaluation(
        episodes=0, valid=False, num_walls=level.num_walls, optimal_path_length=0,
        max_steps=level.max_steps, success_rate=0.0, mean_path_length=0.0,
        episode_lengths=np.zeros(0, dtype=np.int64), successes=np.zeros(0, dtype=bool),
        occupancy=np.zeros(level.walls.shape, dtype=np.float32), explored_fraction=0.0,
        repeated_visits=0.0, start=level.start, goal=level.goal,
    )


def _run_levels(levels: list[MazeLevel], agent: Agent, *, episodes: int, seed: int,
                see_through_walls: bool) -> list[MazeEvaluation]:
    """:func:`evaluate_levels` for valid levels: level ``j`` plays episodes ``j·episodes … (j+1)·episodes − 1``."""
    total = len(levels) * episodes
    check_episode_memory(total, levels[0].walls.shape)
    rng = np.random.default_rng(seed)
    sim = BatchedMazeSimulator(levels, see_through_walls=see_through_walls)
    obs = sim.reset(rng.integers(0, 4, size=total), np.repeat(np.arange(len(levels)), episodes))
    state = agent.initial_state(total)
    height, width = levels[0].walls.shape
    # Per-episode visit counts on the padded grid, indexed [episode, x, y] like the simulator.
    visits = np.zeros((total, width + 2, height + 2), dtype=np.int32)
    lengths = np.zeros(total, dtype=np.int64)
    successes = np.zeros(total, dtype=bool)
    running = np.arange(total)
    while running.size:
        # ``running`` holds distinct episodes, so plain fancy-index += counts every visit.
        visits[running, sim.positions[:, 0], sim.positions[:, 1]] += 1
        actions, state = agent.act(obs, state, rng)
        obs, _, terminated, truncated = sim.step(actions)
        done = terminated | truncated
        if done.any():
            successes[running[terminated]] = True
            lengths[running[done]] = sim.step_counts[done]
            alive = np.flatnonzero(~done)
            sim.keep(alive)
            state = agent.select_state(state, alive)
            obs = {key: value[alive] for key, value in obs.items()}
            running = running[alive]

    interior = visits[:, 1:-1, 1:-1].transpose(0, 2, 1)  # → [episode, row, col]
    return [_summary(level, interior[j * episodes:(j + 1) * episodes], lengths[j * episodes:(j + 1) * episodes],
                     successes[j * episodes:(j + 1) * episodes], max_steps=sim.max_steps)
            for j, level in enumerate(levels)]


def _summary(level: MazeLevel, interior: np.ndarray, lengths: np.ndarray, successes: np.ndarray, *,
             max_steps: int) -> MazeEvaluation:
    """One level's evaluation from its episodes' visit counts ``[episode, row, col]``, lengths and successes."""
    episodes = len(lengths)
    occupied = interior > 0
    occupied[successes, level.goal[0], level.goal[1]] = True
    reachable = level.reachable_cells
    return MazeEvaluation(
        episodes=episodes,
        valid=True,
        num_walls=level.num_walls,
        optimal_path_length=level.optimal_path_length,
        max_steps=max_steps,
        success_rate=float(successes.mean()),
        # A failed episode ran to truncation, so its length already is max_steps.
        mean_path_length=float(lengths.mean()),
        episode_lengths=lengths,
        successes=successes,
        occupancy=(interior.sum(axis=0) / episodes).astype(np.float32),
        explored_fraction=float((occupied & reachable).sum(axis=(1, 2)).mean() / reachable.sum()),
        repeated_visits=float((interior.sum(axis=(1, 2)) - (interior > 0).sum(axis=(1, 2))).mean()),
        start=level.start,
        goal=level.goal,
    )
