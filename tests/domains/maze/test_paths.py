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
