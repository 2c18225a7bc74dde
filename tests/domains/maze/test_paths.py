import subprocess
import sys

import numpy as np
import pytest
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import shortest_path

from dsage_ray.domains.maze.paths import distances_from, furthest_pairs


def _adjacency(empty: np.ndarray) -> tuple[csr_matrix, np.ndarray]:
    """scipy's 4-neighbour graph over the empty cells, numbered in row-major order, and each node's flat cell."""
    node = np.full(empty.shape, -1, dtype=np.int64)
    flat = np.flatnonzero(empty)
    node.flat[flat] = np.arange(flat.size)
    right = empty[:, :-1] & empty[:, 1:]
    down = empty[:-1, :] & empty[1:, :]
    src = np.concatenate([node[:, :-1][right], node[:-1, :][down]])
    dst = np.concatenate([node[:, 1:][right], node[1:, :][down]])
    rows, cols = np.concatenate([src, dst]), np.concatenate([dst, src])
    return csr_matrix((np.ones(rows.size, dtype=np.int8), (rows, cols)), shape=(flat.size, flat.size)), flat


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


@pytest.mark.parametrize("density", [0.0, 0.3, 0.6])
def test_distances_from_match_scipy(density):
    rng = np.random.default_rng(int(density * 10))
    for walls in rng.random((20, 7, 11)) < density:
        graph, flat = _adjacency(~walls)
        if not flat.size:
            continue
        source = int(rng.choice(flat))
        expected = np.full(walls.shape, -1.0)
        reached = shortest_path(graph, directed=False, unweighted=True, indices=int(np.searchsorted(flat, source)))
        expected.flat[flat] = np.where(np.isfinite(reached), reached, -1)
        assert np.array_equal(distances_from(walls, divmod(source, walls.shape[1])), expected)



def test_compile_kernels_compiles_the_kernel_behind_each_public_function():
    # A fresh process: this one's kernels were compiled by the tests above. (The kernels those four call are compiled
    # into them.)
    code = ("from dsage_ray.domains.maze import paths; paths.compile_kernels(); "
            "print(*(bool(paths._furthest_pairs.signatures), bool(paths._path_masks.signatures), "
            "bool(paths._pair_distances.signatures), bool(paths._distances_from.signatures)))")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert done.stdout.split() == ["True"] * 4
