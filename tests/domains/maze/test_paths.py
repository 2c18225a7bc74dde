import numpy as np
import pytest
from scipy.sparse.csgraph import shortest_path

from dsage_ray.domains.maze.level import _adjacency
from dsage_ray.domains.maze.paths import furthest_pairs


def scipy_furthest_pair(walls: np.ndarray):
    """SPEC §2's definition, literally: argmax of the row-major all-pairs distance matrix."""
    graph, flat = _adjacency(~walls)
    if flat.size < 2:
        return None
    dist = shortest_path(graph, directed=False, unweighted=True)
    dist[~np.isfinite(dist)] = -1
    i, j = divmod(int(np.argmax(dist)), flat.size)
    return None if dist[i, j] <= 0 else (int(flat[i]), int(flat[j]), int(dist[i, j]))


@pytest.mark.parametrize("shape", [(16, 16), (5, 9), (13, 13), (2, 2), (1, 7)])
def test_batched_search_matches_the_all_pairs_definition(shape):
    rng = np.random.default_rng(sum(shape))
    walls = np.concatenate([rng.random((40,) + shape) < p for p in (0.0, 0.2, 0.45, 0.7, 0.95)])
    for maze, (start, goal, length) in zip(walls, furthest_pairs(walls)):
        expected = scipy_furthest_pair(maze)
        if expected is None:
            assert (start, goal, length) == (-1, -1, -1)
        else:
            assert (start, goal, length) == expected


def test_rejects_a_single_bitmap():
    with pytest.raises(ValueError, match=r"\(n, H, W\)"):
        furthest_pairs(np.zeros((4, 4), dtype=bool))


def _tree_maze(rng, size):
    """A perfect maze (a spanning tree of the odd cells, by randomised DFS): every pair has one path, and the
    diameter is long, the case where eccentricity bounds prune least."""
    walls = np.ones((size, size), dtype=bool)
    stack = [(0, 0)]
    walls[0, 0] = False
    while stack:
        r, c = stack[-1]
        steps = [(dr, dc) for dr, dc in ((0, 2), (2, 0), (0, -2), (-2, 0))
                 if 0 <= r + dr < size and 0 <= c + dc < size and walls[r + dr, c + dc]]
        if not steps:
            stack.pop()
            continue
        dr, dc = steps[rng.integers(len(steps))]
        walls[r + dr // 2, c + dc // 2] = walls[r + dr, c + dc] = False
        stack.append((r + dr, c + dc))
    return walls


def test_the_bounded_search_matches_the_definition_on_trees_rooms_and_tied_components():
    rng = np.random.default_rng(7)
    mazes = [_tree_maze(rng, 15) for _ in range(20)]
    # Trees with a few walls knocked out (cycles), open rooms (many tied pairs), and two equal components side
    # by side, whose tie the row-major first cell breaks.
    for maze in mazes[:10]:
        knocked = maze.copy()
        knocked[rng.integers(0, 15, 8), rng.integers(0, 15, 8)] = False
        mazes.append(knocked)
    mazes += [np.zeros((15, 15), dtype=bool), np.pad(np.zeros((5, 5), dtype=bool), 5, constant_values=True)]
    twin = np.ones((15, 15), dtype=bool)
    twin[1:6, 1:6] = twin[8:13, 1:6] = twin[1:6, 8:13] = False
    mazes.append(twin)
    walls = np.stack(mazes)
    for maze, (start, goal, length) in zip(walls, furthest_pairs(walls)):
        assert (start, goal, length) == scipy_furthest_pair(maze)
