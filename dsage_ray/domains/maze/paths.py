"""Batched furthest-pair search: the hot path of encoding mazes for the surrogate's inner loop.

Every surrogate prediction needs the level's start and goal, the furthest pair of its empty cells. Per
maze through scipy's all-pairs shortest paths that is ~1–4 ms of Python and sparse-matrix set-up, more
than the prediction itself. Here compiled BFS find it, and eccentricity bounds (Takes & Kosters,
"Determining the diameter of small world networks", CIKM 2011) spare most of them, for the same pair
(tests/domains/maze/test_paths.py; ``benchmarks/bench_furthest_pairs.py`` times it against one BFS per empty cell).
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
def _furthest_pair(flat: np.ndarray, height: int, width: int, dist: np.ndarray, queue: np.ndarray,
                   lower: np.ndarray, upper: np.ndarray, out: np.ndarray) -> None:  # pragma: no cover - compiled
    """The furthest pair of one maze (the SPEC's first maximum), into ``out``; ``dist`` must be -1 on entry and is
    left so. Eccentricity bounds (Takes & Kosters' BoundingDiameters) spare most of the all-pairs BFS."""
    size = height * width
    unknown = size + 1
    count = 0
    for cell in range(size):
        lower[cell] = 0
        upper[cell] = unknown if flat[cell] else -1
        count += flat[cell]
    if count < 2:
        return
    # 1. The diameter: BFS from the cell with the highest upper bound, then the lowest lower bound, in turn, until
    #    no cell's eccentricity can exceed the longest found. A BFS from v bounds every cell w of its component:
    #    max(d, ecc(v) - d) <= ecc(w) <= ecc(v) + d, with d = d(v, w).
    best = 0
    turn = 0
    while True:
        pick = -1
        for cell in range(size):
            if upper[cell] <= best or lower[cell] == upper[cell]:
                continue
            if pick < 0 or (upper[cell] > upper[pick] if turn == 0 else lower[cell] < lower[pick]):
                pick = cell
        if pick < 0:
            break
        turn = 1 - turn
        best = max(best, _bound_from(flat, height, width, pick, dist, queue, lower, upper))
    if best == 0:
        return
    # 2. The start: the first cell in row-major order whose eccentricity is the diameter; the goal: the first cell
    #    that far from it.
    for cell in range(size):
        if upper[cell] < best:
            continue
        if lower[cell] < upper[cell]:
            _bound_from(flat, height, width, cell, dist, queue, lower, upper)
        if lower[cell] == best:
            tail = _bfs(flat, height, width, cell, dist, queue)
            goal = size
            for k in range(tail):
                if dist[queue[k]] == best and queue[k] < goal:
                    goal = queue[k]
                dist[queue[k]] = -1
            out[0], out[1], out[2] = cell, goal, best
            return


@numba.njit(cache=True, nogil=True)
def _bound_from(flat: np.ndarray, height: int, width: int, source: int, dist: np.ndarray, queue: np.ndarray,
                lower: np.ndarray, upper: np.ndarray) -> int:  # pragma: no cover - compiled
    """BFS from ``source``: tightens the eccentricity bounds of its component and returns ``ecc(source)``."""
    tail = _bfs(flat, height, width, source, dist, queue)
    ecc = dist[queue[tail - 1]]
    for k in range(tail):
        cell = queue[k]
        d = dist[cell]
        lower[cell] = max(lower[cell], d, ecc - d)
        upper[cell] = min(upper[cell], ecc + d)
        dist[cell] = -1
    lower[source] = ecc
    upper[source] = ecc
    return ecc


@numba.njit(cache=True, nogil=True)
def _furthest_pairs(empty: np.ndarray) -> np.ndarray:  # pragma: no cover - compiled
    n, height, width = empty.shape
    size = height * width
    out = np.full((n, 3), -1, dtype=np.int64)
    dist = np.full(size, -1, dtype=np.int64)
    queue = np.empty(size, dtype=np.int64)
    lower = np.empty(size, dtype=np.int64)
    upper = np.empty(size, dtype=np.int64)
    for m in range(n):
        _furthest_pair(empty[m].ravel(), height, width, dist, queue, lower, upper, out[m])
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


@numba.njit(cache=True, nogil=True)
def _distances_from(empty: np.ndarray, source: int) -> np.ndarray:  # pragma: no cover - compiled
    height, width = empty.shape
    dist = np.full(height * width, -1, dtype=np.int64)
    _bfs(empty.ravel(), height, width, source, dist, np.empty(height * width, dtype=np.int64))
    return dist.reshape(height, width)


def distances_from(walls: np.ndarray, cell: tuple[int, int]) -> np.ndarray:
    """Forward moves from ``cell`` to every cell of one maze along 4-neighbour shortest paths.

    Args:
        walls: ``(H, W)`` bool wall bitmap.
        cell: Interior ``(row, col)`` of an empty cell (not checked: a wall gives distance 0 there only).

    Returns:
        ``(H, W)`` int64: 0 at ``cell``, -1 on walls and on cells not connected to it.
    """
    empty = np.ascontiguousarray(~np.asarray(walls, dtype=bool))
    return _distances_from(empty, int(cell[0]) * empty.shape[1] + int(cell[1]))


def compile_kernels() -> None:
    """Compiles every kernel into numba's on-disk cache, so that later processes load them.

    A cold kernel cache costs each process that evaluates mazes about 4 s of compiling until one of them has
    written it. ``make test`` calls this before its parallel workers start.
    """
    walls = np.ones((1, 3, 3), dtype=bool)
    walls[0, 1, 1] = False
    pairs = furthest_pairs(walls)
    path_masks(walls, pairs)
    pair_distances(walls, pairs[:, 0], pairs[:, 1])
    distances_from(walls[0], (1, 1))
