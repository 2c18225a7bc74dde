"""A Maze level: an interior wall bitmap plus its start and goal cells (SPEC: the Maze).

Coordinates are interior ``(row, col)`` throughout this package; the surrounding border wall is
implied, so bitmap cell ``[row, col]`` sits at MiniGrid grid position ``(x=col + 1, y=row + 1)``.
"""

from __future__ import annotations

import dataclasses
import functools

import numpy as np

from dsage_ray.domains.maze.paths import distances_from, furthest_pairs

Cell = tuple[int, int]


def path_distances(walls: np.ndarray, cell: Cell) -> np.ndarray:
    """Forward moves from ``cell`` to every interior cell along 4-neighbour shortest paths.

    Args:
        walls: ``(H, W)`` bool wall bitmap.
        cell: Interior ``(row, col)`` of an empty cell.

    Returns:
        ``(H, W)`` float64: 0 at ``cell``, ``inf`` on walls and on cells not connected to it.

    Raises:
        ValueError: ``cell`` is a wall.
    """
    walls = np.asarray(walls, dtype=bool)
    if walls[cell]:
        raise ValueError(f"cell {tuple(cell)} is a wall")
    moves = distances_from(walls, cell)
    return np.where(moves >= 0, moves.astype(np.float64), np.inf)


def max_steps_for(height: int, width: int) -> int:
    """Episode step limit of an ``height × width`` interior: ``2·(H+2)·(W+2)`` (648 for 16×16)."""
    return 2 * (height + 2) * (width + 2)


def furthest_pair(walls: np.ndarray) -> tuple[Cell, Cell] | None:
    """The two connected empty cells furthest apart by 4-neighbour shortest path.

    Ties go to the first maximum in row-major order of the (start, goal) distance matrix, whose
    rows and columns are the empty cells in row-major order; the start therefore has the smaller
    flat index. Returns ``None`` when no two empty cells are connected.
    """
    walls = np.asarray(walls, dtype=bool)
    start, goal, _ = furthest_pairs(walls[None])[0]
    if start < 0:
        return None
    width = walls.shape[1]
    return divmod(int(start), width), divmod(int(goal), width)


@dataclasses.dataclass(frozen=True, eq=False)
class MazeLevel:
    """An interior wall bitmap with its start and goal.

    Build one with :meth:`from_bitmap` rather than directly: it computes the default start/goal and
    checks explicit ones.

    Attributes:
        walls: ``(H, W)`` bool, True where the interior cell is a wall; read-only.
        start: Interior ``(row, col)`` of the agent's start, or None for a level without one.
        goal: Interior ``(row, col)`` of the goal, or None.
    """

    walls: np.ndarray
    start: Cell | None = None
    goal: Cell | None = None

    @classmethod
    def from_bitmap(cls, bitmap: np.ndarray, start: Cell | None = None, goal: Cell | None = None) -> "MazeLevel":
        """Builds a level from a wall bitmap (anything ``> 0`` is a wall).

        Args:
            bitmap: ``(H, W)`` array, H and W at least 2.
            start: Explicit start cell; needs ``goal`` too. Default: the furthest connected pair.
            goal: Explicit goal cell.

        Raises:
            ValueError: A bitmap that is not 2-D or smaller than 2×2, only one of start/goal, or a
                start/goal outside the bitmap, on a wall, or equal to each other.
        """
        walls = np.array(bitmap, copy=True)
        if walls.ndim != 2 or walls.shape[0] < 2 or walls.shape[1] < 2:
            raise ValueError(f"a maze bitmap must be 2-D and at least 2x2, got shape {walls.shape}")
        walls = walls > 0
        walls.setflags(write=False)
        if (start is None) != (goal is None):
            raise ValueError("give both start and goal, or neither")
        if start is None:
            pair = furthest_pair(walls)
            start, goal = pair if pair is not None else (None, None)
        else:
            start, goal = (int(start[0]), int(start[1])), (int(goal[0]), int(goal[1]))
            for name, cell in (("start", start), ("goal", goal)):
                if not (0 <= cell[0] < walls.shape[0] and 0 <= cell[1] < walls.shape[1]):
                    raise ValueError(f"{name} {cell} lies outside the {walls.shape[0]}x{walls.shape[1]} maze")
                if walls[cell]:
                    raise ValueError(f"{name} {cell} is a wall")
            if start == goal:
                raise ValueError(f"start and goal are the same cell {start}")
        return cls(walls=walls, start=start, goal=goal)

    # ------------------------------------------------------------------------------------ shape

    @property
    def height(self) -> int:
        return int(self.walls.shape[0])

    @property
    def width(self) -> int:
        return int(self.walls.shape[1])

    @property
    def max_steps(self) -> int:
        """Episode step limit: ``2·(H+2)·(W+2)`` (648 for 16×16)."""
        return max_steps_for(self.height, self.width)

    @property
    def num_walls(self) -> int:
        return int(self.walls.sum())

    # ------------------------------------------------------------------------------ connectivity

    @functools.cached_property
    def _start_distances(self) -> np.ndarray:
        """``(H, W)`` int64 forward moves from the start; -1 on walls, on cells not connected to it, and
        everywhere for a level without a start (or with one on a wall)."""
        if self.start is None or self.walls[self.start]:
            return np.full(self.walls.shape, -1, dtype=np.int64)
        return distances_from(self.walls, self.start)

    @property
    def reachable_cells(self) -> np.ndarray:
        """``(H, W)`` bool: the empty cells connected to the start (start and goal included)."""
        return self._start_distances >= 0

    @property
    def valid(self) -> bool:
        """True when the level has a start and a goal connected to each other (≥2 connected empty cells)."""
        return self.goal is not None and bool(self._start_distances[self.goal] > 0)

    @property
    def optimal_path_length(self) -> int:
        """Forward moves on the shortest 4-neighbour path from start to goal; 0 on an invalid level."""
        return int(self._start_distances[self.goal]) if self.valid else 0
