"""Hand-made and generated test mazes for behavioural agent tests, as :class:`MazeLevel` objects.

Start and goal are the level's default (the furthest connected pair, SPEC §2); episodes run through
:func:`dsage_ray.domains.maze.evaluate`, i.e. the batched simulator that is tested bit-identical to MiniGrid.
"""

from __future__ import annotations

import numpy as np

from dsage_ray.domains.maze import MazeLevel


def labyrinth13() -> MazeLevel:
    """A 13×13 spiral labyrinth: three concentric wall rings, one long corridor spiralling inward.

    One blocking cell per corridor ring makes it a perfect (simply-connected) maze: every wall touches the
    border, and the start→goal path winds through all three rings.
    """
    walls = np.zeros((13, 13), dtype=bool)
    for k in (1, 3, 5):
        walls[k, k : 13 - k] = walls[12 - k, k : 13 - k] = True
        walls[k : 13 - k, k] = walls[k : 13 - k, 12 - k] = True
    walls[1, 6] = walls[9, 6] = walls[5, 6] = False  # ring gaps: top, bottom, top
    walls[0, 7] = walls[2, 7] = walls[8, 7] = True  # blockers: each corridor ring becomes a one-way path
    return MazeLevel.from_bitmap(walls)


def perfect_maze(size: int, seed: int) -> MazeLevel:
    """A random perfect maze (depth-first backtracker) on a ``size``×``size`` bitmap; cells at even indices."""
    rng = np.random.default_rng(seed)
    walls = np.ones((size, size), dtype=bool)
    n = (size + 1) // 2
    stack, seen = [(0, 0)], {(0, 0)}
    walls[0, 0] = False
    while stack:
        r, c = stack[-1]
        options = [
            (r + dr, c + dc)
            for dr, dc in ((1, 0), (-1, 0), (0, 1), (0, -1))
            if 0 <= r + dr < n and 0 <= c + dc < n and (r + dr, c + dc) not in seen
        ]
        if not options:
            stack.pop()
            continue
        nr, nc = options[rng.integers(len(options))]
        walls[2 * nr, 2 * nc] = walls[r + nr, c + nc] = False  # the new cell and the wall between
        seen.add((nr, nc))
        stack.append((nr, nc))
    return MazeLevel.from_bitmap(walls)


def open_maze(size: int, density: float, seed: int) -> MazeLevel:
    """Sparse random walls, redrawn until every empty cell is connected: an easy maze."""
    rng = np.random.default_rng(seed)
    while True:
        level = MazeLevel.from_bitmap(rng.random((size, size)) < density)
        if level.valid and level.reachable_cells.sum() == (~level.walls).sum():
            return level
