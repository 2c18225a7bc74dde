"""One-hot Maze levels for the surrogate model (SPEC §4)."""

from __future__ import annotations

from typing import Sequence

import numpy as np

from dsage_ray.domains.maze.level import MazeLevel

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
    if not isinstance(levels, np.ndarray):
        levels = list(levels)
    if isinstance(levels, np.ndarray):
        bitmaps = np.asarray(levels).reshape(len(levels), height, width) > 0.5
        levels = [MazeLevel.from_bitmap(bitmap) for bitmap in bitmaps]
    out = np.zeros((len(levels), len(CHANNELS), height, width), dtype=np.float32)
    for n, level in enumerate(levels):
        if level.walls.shape != (height, width):
            raise ValueError(f"level {n} is {level.height}x{level.width}, expected {height}x{width}")
        kind = np.where(level.walls, WALL, EMPTY)
        if level.start is not None:
            kind[level.start] = START
            kind[level.goal] = GOAL
        out[n] = np.eye(len(CHANNELS), dtype=np.float32)[kind].transpose(2, 0, 1)
    return out
