"""Env-steps per second: the batched Maze simulator (batch 50) vs stepping the MiniGrid env.

Both run in this process on the same random valid 16×16 mazes with uniformly random actions. The
simulator's figure includes building its per-level lookup tables (once per maze, as an evaluation
does). Times are CPU time of this process (``time.process_time``), so other load on a shared
machine affects them less; wall time is printed too. Target: ratio ≥ 25×.

Run: ``.venv/bin/python benchmarks/bench_maze_simulator.py [--mazes N]``
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from dsage_ray.domains.maze.env import MazeEnv
from dsage_ray.domains.maze.generator import random_valid_levels
from dsage_ray.domains.maze.level import MazeLevel
from dsage_ray.domains.maze.simulator import BatchedMazeSimulator

BATCH = 50
#: Wall densities of the benchmark mazes (sparse to dense enough for long episodes).
DENSITY_RANGE = (0.1, 0.4)


def bench_simulator(levels: list[MazeLevel], rng: np.random.Generator) -> tuple[int, float, float]:
    """Full evaluations' worth of stepping: 50 episodes per maze until every one has ended."""
    steps = 0
    cpu, wall = time.process_time(), time.perf_counter()
    for level in levels:
        sim = BatchedMazeSimulator(level)
        sim.reset(rng.integers(0, 4, size=BATCH))
        while sim.num_episodes:
            _, _, terminated, truncated = sim.step(rng.integers(0, 7, size=sim.num_episodes))
            steps += sim.num_episodes
            sim.keep(np.flatnonzero(~(terminated | truncated)))
    return steps, time.process_time() - cpu, time.perf_counter() - wall


def bench_minigrid(levels: list[MazeLevel], rng: np.random.Generator, steps_per_level: int) -> tuple[int, float, float]:
    """The same kind of episodes, one MiniGrid env stepped at a time (reset on episode end)."""
    steps = 0
    cpu, wall = time.process_time(), time.perf_counter()
    for i, level in enumerate(levels):
        env = MazeEnv(level)
        env.reset(seed=i)
        for action in rng.integers(0, 7, size=steps_per_level):
            _, _, terminated, truncated, _ = env.step(int(action))
            steps += 1
            if terminated or truncated:
                env.reset()
    return steps, time.process_time() - cpu, time.perf_counter() - wall


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--mazes", type=int, default=10, help="random 16x16 mazes (default 10)")
    parser.add_argument("--minigrid-steps", type=int, default=3000, help="MiniGrid steps per maze (default 3000)")
    args = parser.parse_args()
    levels = random_valid_levels(args.mazes, seed=0, density_range=DENSITY_RANGE)
    bench_simulator(levels[:1], np.random.default_rng(1))  # warm-up (imports, caches)

    sim_steps, sim_cpu, sim_wall = bench_simulator(levels, np.random.default_rng(2))
    mg_steps, mg_cpu, mg_wall = bench_minigrid(levels, np.random.default_rng(3), args.minigrid_steps)
    sim_rate, mg_rate = sim_steps / sim_cpu, mg_steps / mg_cpu
    print(f"mazes: {args.mazes} random valid 16x16, uniformly random actions")
    print(f"batched simulator (batch {BATCH}): {sim_steps:8d} steps  {sim_cpu:6.2f} s CPU  "
          f"{sim_rate:10,.0f} steps/s  (wall {sim_steps / sim_wall:10,.0f} steps/s)")
    print(f"MiniGrid env.step            : {mg_steps:8d} steps  {mg_cpu:6.2f} s CPU  "
          f"{mg_rate:10,.0f} steps/s  (wall {mg_steps / mg_wall:10,.0f} steps/s)")
    print(f"ratio (CPU steps/s): {sim_rate / mg_rate:.1f}x  (target >= 25x)")


if __name__ == "__main__":
    main()
