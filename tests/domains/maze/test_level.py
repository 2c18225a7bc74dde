from collections import deque

import numpy as np
import pytest

from dsage_ray.domains.maze.level import MazeLevel, furthest_pair, path_distances


def _bfs(walls: np.ndarray, source: tuple[int, int]) -> dict[tuple[int, int], int]:
    """Plain-Python BFS: an independent reference for the scipy-based code."""
    dist = {source: 0}
    queue = deque([source])
    while queue:
        r, c = queue.popleft()
        for nr, nc in ((r - 1, c), (r + 1, c), (r, c - 1), (r, c + 1)):
            if 0 <= nr < walls.shape[0] and 0 <= nc < walls.shape[1] and not walls[nr, nc] and (nr, nc) not in dist:
                dist[(nr, nc)] = dist[(r, c)] + 1
                queue.append((nr, nc))
    return dist


def _reference_pair(walls: np.ndarray):
    """First maximum, row-major over (start, goal) with cells in row-major order."""
    cells = [(r, c) for r in range(walls.shape[0]) for c in range(walls.shape[1]) if not walls[r, c]]
    best, pair = 0, None
    for s in cells:
        dist = _bfs(walls, s)
        for g in cells:
            if dist.get(g, -1) > best:
                best, pair = dist[g], (s, g)
    return pair, best


def test_tie_break_on_open_square():
    # Both diagonals are 4 apart; the row-major first maximum is (0,0) → (2,2).
    level = MazeLevel.from_bitmap(np.zeros((3, 3)))
    assert (level.start, level.goal) == ((0, 0), (2, 2))
    assert level.optimal_path_length == 4


def test_tie_break_prefers_smaller_start_index():
    # A U-shaped corridor: its two ends are the furthest pair (both orders tie); the start is the
    # end with the smaller flat index.
    walls = np.array([[0, 1, 0], [0, 1, 0], [0, 0, 0]])
    level = MazeLevel.from_bitmap(walls)
    assert (level.start, level.goal) == ((0, 0), (0, 2))


@pytest.mark.parametrize("seed", range(15))
def test_furthest_pair_matches_reference_bfs(seed):
    rng = np.random.default_rng(seed)
    walls = rng.random((rng.integers(2, 9), rng.integers(2, 9))) < 0.35
    pair, best = _reference_pair(walls)
    assert furthest_pair(walls) == pair
    level = MazeLevel.from_bitmap(walls)
    assert level.valid == (pair is not None)
    assert level.optimal_path_length == best


def test_properties_and_coordinates():
    walls = np.zeros((16, 16), dtype=bool)
    walls[3, 4:10] = True
    walls[10:, 8] = True
    level = MazeLevel.from_bitmap(walls)
    assert (level.height, level.width, level.max_steps, level.num_walls) == (16, 16, 648, 12)
    assert level.valid and level.reachable_cells.sum() == 256 - 12
    assert not level.walls.flags.writeable


def test_rectangular_max_steps_and_reachable():
    walls = np.array([[0, 0, 1, 0, 0], [0, 0, 1, 0, 1]])
    level = MazeLevel.from_bitmap(walls)
    assert level.max_steps == 2 * 4 * 7
    # The two sides are disconnected: only the start's side is reachable.
    assert level.reachable_cells[level.start] and level.reachable_cells.sum() == 4


@pytest.mark.parametrize("bitmap", [np.ones((4, 4)), np.array([[0, 1], [1, 0]]), np.array([[0, 1], [1, 1]])])
def test_invalid_levels(bitmap):
    level = MazeLevel.from_bitmap(bitmap)
    assert not level.valid and level.start is None and level.optimal_path_length == 0
    assert not level.reachable_cells.any()


def test_explicit_start_goal_checks():
    walls = np.array([[0, 0, 1], [1, 0, 0]])
    level = MazeLevel.from_bitmap(walls, start=(1, 2), goal=(0, 0))
    assert level.valid and level.optimal_path_length == 3
    with pytest.raises(ValueError, match="wall"):
        MazeLevel.from_bitmap(walls, start=(0, 2), goal=(0, 0))
    with pytest.raises(ValueError, match="outside"):
        MazeLevel.from_bitmap(walls, start=(2, 0), goal=(0, 0))
    with pytest.raises(ValueError, match="both"):
        MazeLevel.from_bitmap(walls, start=(0, 0))
    with pytest.raises(ValueError, match="2x2"):
        MazeLevel.from_bitmap(np.zeros((1, 5)))
    # Explicit but disconnected: a level, just not a valid one.
    assert not MazeLevel.from_bitmap(np.array([[0, 1, 0], [0, 1, 0]]), start=(0, 0), goal=(0, 2)).valid


@pytest.mark.parametrize("seed", range(5))
def test_path_distances_match_reference_bfs(seed):
    walls = np.random.default_rng(seed).random((6, 9)) < 0.35
    source = tuple(int(v) for v in np.argwhere(~walls)[0])
    reference = _bfs(walls, source)
    distances = path_distances(walls, source)
    for cell in np.ndindex(walls.shape):
        assert distances[cell] == reference.get(cell, np.inf)
    with pytest.raises(ValueError, match="is a wall"):
        path_distances(np.ones((2, 2), dtype=bool), (0, 0))
