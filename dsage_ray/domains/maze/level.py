"""A Maze level: an interior wall bitmap plus its start and goal cells (SPEC §2).

Coordinates are interior ``(row, col)`` throughout this package; the surrounding border wall is
implied, so bitmap cell ``[row, col]`` sits at MiniGrid grid position ``(x=col + 1, y=row + 1)``.
"""

from __future__ import annotations

import dataclasses
import functools

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components, shortest_path

from dsage_ray.domains.maze.paths import furthest_pairs

Cell = tuple[int, int]


def _adjacency(empty: np.ndarray) -> tuple[csr_matrix, np.ndarray]:
    """4-neighbour graph over the empty cells of ``empty`` (H, W) bool.

    Returns the sparse adjacency matrix and the flat (row-major) grid index of each node. Nodes are
    numbered in row-major order, which is what makes the start/goal tie-break row-major too.
    """
    height, width = empty.shape
    node = np.full(empty.shape, -1, dtype=np.int64)
    flat = np.flatnonzero(empty)
    node.flat[flat] = np.arange(flat.size)
    # Horizontal and vertical edges between two empty cells, added in both directions.
    right = empty[:, :-1] & empty[:, 1:]
    down = empty[:-1, :] & empty[1:, :]
    src = np.concatenate([node[:, :-1][right], node[:-1, :][down]])
    dst = np.concatenate([node[:, 1:][right], node[1:, :][down]])
    rows = np.concatenate([src, dst])
    cols = np.concatenate([dst, src])
    graph = csr_matrix((np.ones(rows.size, dtype=np.int8), (rows, cols)), shape=(flat.size, flat.size))
    return graph, flat


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
    graph, flat = _adjacency(~walls)
    source = int(np.searchsorted(flat, cell[0] * walls.shape[1] + cell[1]))
    distances = np.full(walls.shape, np.inf)
    distances.flat[flat] = shortest_path(graph, directed=False, unweighted=True, indices=source)
    return distances


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
    def _components(self) -> np.ndarray:
        """``(H, W)`` int: connected-component label per empty cell, -1 on walls."""
        graph, flat = _adjacency(~self.walls)
        labels = np.full(self.walls.shape, -1, dtype=np.int64)
        if flat.size:
            labels.flat[flat] = connected_components(graph, directed=False)[1]
        return labels

    @property
    def reachable_cells(self) -> np.ndarray:
        """``(H, W)`` bool: the empty cells connected to the start (start and goal included)."""
        if self.start is None:
            return np.zeros(self.walls.shape, dtype=bool)
        return self._components == self._components[self.start]

    @property
    def valid(self) -> bool:
        """True when the level has a start and a goal connected to each other (≥2 connected empty cells)."""
        return self.start is not None and self._components[self.start] == self._components[self.goal]

    @functools.cached_property
    def optimal_path_length(self) -> int:
        """Forward moves on the shortest 4-neighbour path from start to goal; 0 on an invalid level."""
        if not self.valid:
            return 0
        return int(path_distances(self.walls, self.start)[self.goal])
