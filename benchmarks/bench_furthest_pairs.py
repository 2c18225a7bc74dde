"""Microseconds per maze of the furthest-pair search (every surrogate prediction's start and goal), against one BFS
per empty cell, on the same mazes; checks that both find the same pairs.

    python benchmarks/bench_furthest_pairs.py [--mazes 3000] [--data FILE.npz]

Mazes: random valid 16×16 mazes, the MAP-Elites mutants of them an inner loop predicts (10 cells flipped), and,
with ``--data``, a dataset's levels (``benchmarks/maze_dataset.py``, e.g. a search's own). One core, CPU time.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numba
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from dsage_ray.domains.maze.generator import random_valid_levels  # noqa: E402
from dsage_ray.domains.maze.paths import _bfs, furthest_pairs  # noqa: E402


@numba.njit(cache=True)
def _all_sources(empty: np.ndarray) -> np.ndarray:  # pragma: no cover - compiled
    """The reference: a BFS from every empty cell, the first maximum in row-major order."""
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
            far = dist[queue[tail - 1]]
            if far > best:
                best = far
                goal = size
                for k in range(tail):
                    if dist[queue[k]] == far and queue[k] < goal:
                        goal = queue[k]
                out[m, 0], out[m, 1], out[m, 2] = source, goal, best
            for k in range(tail):
                dist[queue[k]] = -1
    return out


def _time(function, walls: np.ndarray) -> tuple[np.ndarray, float]:
    function(walls[:4])  # compiled before timing
    tic = time.process_time()
    result = function(walls)
    return result, 1e6 * (time.process_time() - tic) / len(walls)


def main(argv: list[str] | None = None) -> dict[str, float]:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--mazes", type=int, default=3000)
    parser.add_argument("--data", default="", help="also a Maze dataset's levels (.npz)")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    rng = np.random.default_rng(args.seed)
    random = np.stack([level.walls for level in random_valid_levels(args.mazes, seed=args.seed)])
    mutants = random.reshape(len(random), -1).copy()
    for row in mutants:
        row[rng.choice(row.size, 10, replace=False)] = rng.random(10) < 0.5
    sets = {"random valid mazes": random, "their mutants (10 cells)": mutants.reshape(random.shape)}
    if args.data:
        from maze_dataset import load

        data = load(args.data)
        sets[f"levels of {Path(args.data).name}"] = data.solutions().reshape(-1, *data.shape) > 0.5
    speedups = {}
    for name, walls in sets.items():
        walls = np.ascontiguousarray(walls, dtype=bool)
        reference, reference_us = _time(lambda w: _all_sources(~w), walls)
        bounded, bounded_us = _time(furthest_pairs, walls)
        same = np.array_equal(reference, bounded)
        speedups[name] = reference_us / bounded_us
        print(f"{name}: {len(walls)} mazes, one BFS per empty cell {reference_us:.1f} µs, bounded "
              f"{bounded_us:.1f} µs per maze: {speedups[name]:.1f}x, same pairs: {same}")
        if not same:
            raise SystemExit(f"{name}: the bounded search found other pairs than the reference")
    return speedups


if __name__ == "__main__":
    main()
