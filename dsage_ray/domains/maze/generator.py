"""Random valid mazes: *the* distribution of "random valid 16×16 mazes" in this project.

Every interior cell is a wall with probability ``density``, drawn per maze uniformly from
``density_range``, and the level is kept if it is valid (start and goal = the furthest connected
pair, as everywhere else). The agent benchmark and the simulator benchmarks evaluate fixed seeded
sets of them; agent training samples a fresh one on every reset.
"""

from __future__ import annotations

import numpy as np

from dsage_ray.domains.maze.level import MazeLevel

#: Wall density range of the benchmark and training mazes.
DEFAULT_DENSITY_RANGE = (0.0, 0.5)


def random_valid_level(
    rng: np.random.Generator,
    *,
    height: int = 16,
    width: int = 16,
    density_range: tuple[float, float] = DEFAULT_DENSITY_RANGE,
) -> MazeLevel:
    """A uniformly random wall bitmap at a random density, redrawn until valid.

    Args:
        rng: Source of all randomness (density, then walls).
        height: Interior rows.
        width: Interior columns.
        density_range: ``(low, high)`` wall probability range; one density is drawn per maze.
    """
    while True:
        density = rng.uniform(*density_range)
        level = MazeLevel.from_bitmap(rng.random((height, width)) < density)
        if level.valid:
            return level


def random_valid_levels(n: int, *, seed: int, height: int = 16, width: int = 16,
                        density_range: tuple[float, float] = DEFAULT_DENSITY_RANGE) -> list[MazeLevel]:
    """``n`` levels from :func:`random_valid_level`, a fixed set for a given seed."""
    rng = np.random.default_rng(seed)
    return [random_valid_level(rng, height=height, width=width, density_range=density_range) for _ in range(n)]
