"""Batched furthest-pair search: the hot path of encoding mazes for the surrogate's inner loop.

Every surrogate prediction needs the level's start and goal, i.e. the all-pairs shortest paths of
its empty cells. Per maze through scipy that is ~1–4 ms of Python and sparse-matrix set-up, more
than the prediction itself; here one compiled BFS per empty cell does the same in microseconds.
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True, nogil=True)
def _bfs(flat: np.ndarray, height: int, width: int, source: int, dist: np.ndarray,
         queue: np.ndarray) -> int:  # pragma: no cover - compiled
    """4-neighbour BFS over the empty cells ``flat`` from ``source``; ``dist`` must be -1 on entry.

    Fills ``dist`` for the reached cells and ``queue[:tail]`` with them in visiting order (non-decreasing
    distance); returns ``tail``.
    """
    dist[source] = 0
    queue[0] = source
    head, tail = 0, 1
    while head < tail:
        cell = queue[head]
        head += 1
        row, col = cell // width, cell % width
        d = dist[cell] + 1
        if row > 0 and flat[cell - width] and dist[cell - width] < 0:
            dist[cell - width] = d
            queue[tail] = cell - width
            tail += 1
        if row < height - 1 and flat[cell + width] and dist[cell + width] < 0:
            dist[cell + width] = d
            queue[tail] = cell + width
            tail += 1
        if col > 0 and flat[cell - 1] and dist[cell - 1] < 0:
            dist[cell - 1] = d
            queue[tail] = cell - 1
            tail += 1
        if col < width - 1 and flat[cell + 1] and dist[cell + 1] < 0:
            dist[cell + 1] = d
            queue[tail] = cell + 1
            tail += 1
    return tail


@numba.njit(cache=True, nogil=True)
def _furthest_pairs(empty: np.ndarray) -> np.ndarray:  # pragma: no cover - compiled
    n, height, width = empty.shape
    size = height * width
    out = np.full((n, 3), -1, dtype=np.int64)
    dist = np.full(size, -1, dtype=np.int64)
    queue = np.empty(size, dtype=np.int64)
    for m in range(n):
        flat = empty[m].ravel()
        best = 0
        for source in range(size):
            if not flat[source]:
                continue
            tail = _bfs(flat, height, width, source, dist, queue)
            # BFS dequeues in non-decreasing distance, so the furthest targets end the queue.
            # Sources ascend and the distance matrix is symmetric, so SPEC §2's tie-break (first
            # maximum in row-major order) is: a strictly longer distance wins, and among equals
            # the smallest target index, which is always > source for the first maximum.
            far = dist[queue[tail - 1]]
            if far > best:
                best = far
                goal = size
                k = tail - 1
                while k >= 0 and dist[queue[k]] == far:
                    if queue[k] < goal:
                        goal = queue[k]
                    k -= 1
                out[m, 0] = source
                out[m, 1] = goal
                out[m, 2] = best
            for k in range(tail):
                dist[queue[k]] = -1
    return out


def furthest_pairs(walls: np.ndarray) -> np.ndarray:
    """Start, goal and their distance for a batch of mazes.

    Args:
        walls: ``(n, H, W)`` bool wall bitmaps.

    Returns:
        ``(n, 3)`` int64: flat (row-major) start index, flat goal index, shortest-path length;
        ``-1`` everywhere for a maze with no two connected empty cells.
    """
    walls = np.asarray(walls, dtype=bool)
    if walls.ndim != 3:
        raise ValueError(f"expected (n, H, W) bitmaps, got shape {walls.shape}")
    return _furthest_pairs(np.ascontiguousarray(~walls))


@numba.njit(cache=True, nogil=True)
def _path_masks(empty: np.ndarray, pairs: np.ndarray) -> np.ndarray:  # pragma: no cover - compiled
    n, height, width = empty.shape
    size = height * width
    out = np.zeros((n, 2, size), dtype=np.uint8)
    from_start = np.empty(size, dtype=np.int64)
    from_goal = np.empty(size, dtype=np.int64)
    queue = np.empty(size, dtype=np.int64)
    for m in range(n):
        if pairs[m, 0] < 0:
            continue
        flat = empty[m].ravel()
        for which in range(2):
            dist = from_start if which == 0 else from_goal
            dist[:] = -1
            _bfs(flat, height, width, pairs[m, which], dist, queue)
        length = from_start[pairs[m, 1]]
        for cell in range(size):
            if from_start[cell] >= 0:
                out[m, 0, cell] = 1
                if from_goal[cell] >= 0 and from_start[cell] + from_goal[cell] == length:
                    out[m, 1, cell] = 1
    return out.reshape(n, 2, height, width)


def path_masks(walls: np.ndarray, pairs: np.ndarray) -> np.ndarray:
    """The cells an agent can reach from the start, and those on some shortest start-goal path.

    Args:
        walls: ``(n, H, W)`` bool wall bitmaps.
        pairs: ``(n, 3)`` from :func:`furthest_pairs` (start, goal, length; ``-1`` without a pair).

    Returns:
        ``(n, 2, H, W)`` uint8: channel 0 reachable from the start, channel 1 on a shortest path
        to the goal; all zeros for a maze without a start.
    """
    walls = np.asarray(walls, dtype=bool)
    return _path_masks(np.ascontiguousarray(~walls), np.ascontiguousarray(pairs, dtype=np.int64))


@numba.njit(cache=True, nogil=True)
def _pair_distances(empty: np.ndarray, starts: np.ndarray, goals: np.ndarray) -> np.ndarray:  # pragma: no cover
    n, height, width = empty.shape
    size = height * width
    out = np.full(n, -1, dtype=np.int64)
    dist = np.full(size, -1, dtype=np.int64)
    queue = np.empty(size, dtype=np.int64)
    for m in range(n):
        if starts[m] < 0 or not empty[m].ravel()[starts[m]]:
            continue
        tail = _bfs(empty[m].ravel(), height, width, starts[m], dist, queue)
        out[m] = dist[goals[m]]
        for k in range(tail):
            dist[queue[k]] = -1
    return out


def pair_distances(walls: np.ndarray, starts: np.ndarray, goals: np.ndarray) -> np.ndarray:
    """Shortest 4-neighbour path lengths from each maze's start to its goal.

    Args:
        walls: ``(n, H, W)`` bool wall bitmaps.
        starts: ``(n,)`` flat (row-major) start cells; ``-1`` for a maze without one.
        goals: ``(n,)`` flat goal cells.

    Returns:
        ``(n,)`` int64 forward moves; ``-1`` where there is no start or the goal is not reachable from it.
    """
    walls = np.asarray(walls, dtype=bool)
    if walls.ndim != 3:
        raise ValueError(f"expected (n, H, W) bitmaps, got shape {walls.shape}")
    return _pair_distances(np.ascontiguousarray(~walls), np.ascontiguousarray(starts, dtype=np.int64),
                           np.ascontiguousarray(goals, dtype=np.int64))
