"""Test-local mazes and a MiniGrid 3.2 environment configured as in SPEC §2, for behavioural agent tests.

This stands in for :mod:`dsage_ray.domains.maze` while that package is being written; it steps real
MiniGrid environments (slow but authoritative) in lock-step so the agent sees batched observations, the way
an evaluation feeds it. Mazes are interior wall bitmaps (``True`` = wall); the border wall is implied.
"""

from __future__ import annotations

import collections

import numpy as np
from minigrid.core.grid import Grid
from minigrid.core.mission import MissionSpace
from minigrid.core.world_object import Goal, Wall
from minigrid.minigrid_env import MiniGridEnv

from dsage_ray.agents import Agent


def parse(rows: list[str]) -> np.ndarray:
    """``#`` wall, ``.`` empty -> bool bitmap ``[row, col]``."""
    return np.array([[ch == "#" for ch in row] for row in rows], dtype=bool)


def furthest_pair(walls: np.ndarray) -> tuple[tuple[int, int], tuple[int, int]]:
    """The two empty cells furthest apart by 4-neighbour BFS, as (row, col); first maximum in row-major order."""
    h, w = walls.shape
    cells = [(r, c) for r in range(h) for c in range(w) if not walls[r, c]]
    best, pair = -1, None
    for start in cells:
        dist = _bfs(walls, start)
        for goal in cells:
            d = dist.get(goal, -1)
            if d > best:
                best, pair = d, (start, goal)
    return pair


def _bfs(walls: np.ndarray, start: tuple[int, int]) -> dict[tuple[int, int], int]:
    dist = {start: 0}
    queue = collections.deque([start])
    while queue:
        r, c = queue.popleft()
        for nr, nc in ((r + 1, c), (r - 1, c), (r, c + 1), (r, c - 1)):
            if 0 <= nr < walls.shape[0] and 0 <= nc < walls.shape[1] and not walls[nr, nc] and (nr, nc) not in dist:
                dist[(nr, nc)] = dist[(r, c)] + 1
                queue.append((nr, nc))
    return dist


def labyrinth13() -> np.ndarray:
    """A 13×13 spiral labyrinth: three concentric wall rings, one long corridor path spiralling to the centre.

    One blocking cell per corridor ring makes it a perfect (simply-connected) maze: every wall touches the border.
    """
    walls = np.zeros((13, 13), dtype=bool)
    for k in (1, 3, 5):
        walls[k, k : 13 - k] = walls[12 - k, k : 13 - k] = True
        walls[k : 13 - k, k] = walls[k : 13 - k, 12 - k] = True
    walls[1, 6] = walls[9, 6] = walls[5, 6] = False  # ring gaps: top, bottom, top
    walls[0, 7] = walls[2, 7] = walls[8, 7] = True  # blockers: each corridor ring becomes a one-way path
    return walls


def perfect_maze(size: int, seed: int) -> np.ndarray:
    """A random perfect maze (depth-first backtracker) on a ``size``×``size`` bitmap; cells at even indices."""
    rng = np.random.default_rng(seed)
    walls = np.ones((size, size), dtype=bool)
    n = (size + 1) // 2
    stack, seen = [(0, 0)], {(0, 0)}
    walls[0, 0] = False
    while stack:
        r, c = stack[-1]
        options = [(r + dr, c + dc) for dr, dc in ((1, 0), (-1, 0), (0, 1), (0, -1))
                   if 0 <= r + dr < n and 0 <= c + dc < n and (r + dr, c + dc) not in seen]
        if not options:
            stack.pop()
            continue
        nr, nc = options[rng.integers(len(options))]
        walls[2 * nr, 2 * nc] = walls[r + nr, c + nc] = False  # the cell and the wall between
        seen.add((nr, nc))
        stack.append((nr, nc))
    return walls


def open_maze(size: int, density: float, seed: int) -> np.ndarray:
    """Sparse random walls, rejected until all empty cells are connected."""
    rng = np.random.default_rng(seed)
    while True:
        walls = rng.random((size, size)) < density
        empty = list(zip(*np.nonzero(~walls)))
        if len(_bfs(walls, empty[0])) == len(empty):
            return walls


class BitmapMazeEnv(MiniGridEnv):
    """A MiniGrid env for one bitmap: 5×5 view, see-through walls, random heading, ``max_steps = 2·(H+2)²``."""

    def __init__(self, walls: np.ndarray, *, see_through_walls: bool = True) -> None:
        self.walls = walls
        self.start, self.goal = furthest_pair(walls)
        height, width = walls.shape[0] + 2, walls.shape[1] + 2
        super().__init__(
            mission_space=MissionSpace(mission_func=lambda: "get to the green goal square"),
            width=width,
            height=height,
            max_steps=2 * max(width, height) ** 2,
            see_through_walls=see_through_walls,
            agent_view_size=5,
        )

    def _gen_grid(self, width: int, height: int) -> None:
        self.grid = Grid(width, height)
        self.grid.wall_rect(0, 0, width, height)
        for r, c in zip(*np.nonzero(self.walls)):
            self.grid.set(c + 1, r + 1, Wall())  # bitmap [row, col] -> grid (x = col + 1, y = row + 1)
        self.put_obj(Goal(), self.goal[1] + 1, self.goal[0] + 1)
        self.agent_pos = (self.start[1] + 1, self.start[0] + 1)
        self.agent_dir = self._rand_int(0, 4)


def run_episodes(walls: np.ndarray, agent: Agent, *, episodes: int, seed: int, see_through_walls: bool = True):
    """Runs ``episodes`` lock-stepped episodes; finished ones leave the batch. Returns (successes, lengths)."""
    envs = [BitmapMazeEnv(walls, see_through_walls=see_through_walls) for _ in range(episodes)]
    obs = [env.reset(seed=seed + i)[0] for i, env in enumerate(envs)]
    rng = np.random.default_rng(seed)
    active = np.arange(episodes)
    state = agent.initial_state(episodes)
    success = np.zeros(episodes, dtype=bool)
    length = np.zeros(episodes, dtype=np.int64)
    while len(active):
        batch = {
            "image": np.stack([obs[i]["image"] for i in active]),
            "direction": np.array([obs[i]["direction"] for i in active], dtype=np.int64),
        }
        actions, state = agent.act(batch, state, rng)
        keep = []
        for j, i in enumerate(active):
            obs[i], reward, terminated, truncated, _ = envs[i].step(int(actions[j]))
            length[i] += 1
            if terminated or truncated:
                success[i] = terminated and reward > 0
            else:
                keep.append(j)
        keep = np.array(keep, dtype=np.int64)
        active = active[keep]
        state = agent.select_state(state, keep)
    return success, length
