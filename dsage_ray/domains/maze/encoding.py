"""One-hot Maze levels for the surrogate model (SPEC §4)."""

from __future__ import annotations

from typing import Sequence

import numpy as np

from dsage_ray.domains.maze.level import MazeLevel
from dsage_ray.domains.maze.paths import furthest_pairs

#: Channel per cell kind; exactly one is hot per cell. ``spare`` is never set (kept for the
#: original model's 5-channel input).
CHANNELS = ("empty", "wall", "start", "goal", "spare")
EMPTY, WALL, START, GOAL, SPARE = range(len(CHANNELS))


def encode_levels(levels: np.ndarray | Sequence[MazeLevel], height: int, width: int) -> np.ndarray:
    """One-hot encodes levels.

    Args:
        levels: ``(n, H·W)`` wall bitmaps (solutions; anything ``> 0.5`` is a wall, start and goal
            are the furthest pair) or a sequence of :class:`MazeLevel` of that size.
        height: H.
        width: W.

    Returns:
        ``(n, 5, H, W)`` float32 with channels :data:`CHANNELS`.
    """
    if isinstance(levels, np.ndarray):
        walls = np.asarray(levels).reshape(len(levels), height, width) > 0.5
        pairs = furthest_pairs(walls)
        kind = np.where(walls, WALL, EMPTY).reshape(len(levels), -1)
        has_pair = pairs[:, 0] >= 0
        rows = np.flatnonzero(has_pair)
        kind[rows, pairs[has_pair, 0]] = START
        kind[rows, pairs[has_pair, 1]] = GOAL
        kind = kind.reshape(len(levels), height, width)
    else:
        kind = np.empty((len(levels), height, width), dtype=np.int64)
        for n, level in enumerate(levels):
            if level.walls.shape != (height, width):
                raise ValueError(f"level {n} is {level.height}x{level.width}, expected {height}x{width}")
            kind[n] = np.where(level.walls, WALL, EMPTY)
            if level.start is not None:
                kind[n][level.start] = START
                kind[n][level.goal] = GOAL
    return np.eye(len(CHANNELS), dtype=np.float32)[kind].transpose(0, 3, 1, 2).copy()
