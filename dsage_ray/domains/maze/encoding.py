"""One-hot Maze levels for the surrogate model (SPEC: the surrogate)."""

from __future__ import annotations

from typing import Sequence

import numpy as np

from dsage_ray.domains.maze.level import MazeLevel
from dsage_ray.domains.maze.paths import furthest_pairs, path_masks

#: Channel per cell kind; exactly one is hot per cell. ``spare`` is never set (kept for the
#: original model's 5-channel input).
CHANNELS = ("empty", "wall", "start", "goal", "spare")
EMPTY, WALL, START, GOAL, SPARE = range(len(CHANNELS))
#: Extra 0/1 channels of ``path_channels``: cells reachable from the start, and cells on a shortest
#: start-goal path. Not in the paper: the occupancy predictor's 3×3 convolutions see 11×11 cells, so
#: without them it cannot tell which corridors lead to the goal across a 16×16 maze.
PATH_CHANNELS = ("reachable", "shortest_path")


def encode_levels(levels: np.ndarray | Sequence[MazeLevel], height: int, width: int, *,
                  path_channels: bool = False) -> np.ndarray:
    """One-hot encodes levels.

    Args:
        levels: ``(n, H·W)`` wall bitmaps (solutions; anything ``> 0.5`` is a wall, start and goal
            are the furthest pair) or a sequence of :class:`MazeLevel` of that size.
        height: H.
        width: W.
        path_channels: Append :data:`PATH_CHANNELS`.

    Returns:
        ``(n, 5, H, W)`` float32 with channels :data:`CHANNELS`, then :data:`PATH_CHANNELS` if asked
        (``(n, 7, H, W)``).
    """
    if isinstance(levels, np.ndarray):
        walls = np.asarray(levels).reshape(len(levels), height, width) > 0.5
        pairs = furthest_pairs(walls)
    else:
        walls = np.empty((len(levels), height, width), dtype=bool)
        pairs = np.full((len(levels), 3), -1, dtype=np.int64)
        for n, level in enumerate(levels):
            if level.walls.shape != (height, width):
                raise ValueError(f"level {n} is {level.height}x{level.width}, expected {height}x{width}")
            walls[n] = level.walls
            if level.start is not None:
                pairs[n, :2] = [row * width + col for row, col in (level.start, level.goal)]
    kind = np.where(walls, WALL, EMPTY).reshape(len(levels), -1)
    has_pair = pairs[:, 0] >= 0
    rows = np.flatnonzero(has_pair)
    kind[rows, pairs[has_pair, 0]] = START
    kind[rows, pairs[has_pair, 1]] = GOAL
    encoded = np.eye(len(CHANNELS), dtype=np.float32)[kind.reshape(len(levels), height, width)].transpose(0, 3, 1, 2)
    if not path_channels:
        return encoded.copy()
    return np.concatenate([encoded, path_masks(walls, pairs).astype(np.float32)], axis=1)
