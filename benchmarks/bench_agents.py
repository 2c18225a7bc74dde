"""Model card numbers: agents on a fixed set of random valid 16×16 mazes.

The maze set is :func:`dsage_ray.domains.maze.generator.random_valid_levels` with a fixed seed: each interior
cell is a wall with a probability drawn per maze from U(0, 0.5); start and goal are the furthest connected
pair (the Maze domain's rule). Maze ``i`` is evaluated with seed ``i`` for every agent, so the agents see
the same initial headings.

Usage::

    nice -n 10 python benchmarks/bench_agents.py                       # shipped PPO, random, wall follower, ACCEL
    python benchmarks/bench_agents.py --agent rllib:tb_logs/ppo_maze/checkpoint --mazes 20
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

import numpy as np
import torch

from dsage_ray.domains.maze.agents import load_maze_agent
from dsage_ray.domains.maze.generator import random_valid_levels
from dsage_ray.domains.maze import evaluate

REPO_ROOT = Path(__file__).resolve().parents[1]
ACCEL = Path(os.environ.get("DSAGE_SHARED_DIR", REPO_ROOT.parent / "shared")) / "models/accel_seed_1/model_20000.tar"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--agent", action="append", help="agent spec (repeatable); default: the model card set")
    parser.add_argument("--mazes", type=int, default=100)
    parser.add_argument("--episodes", type=int, default=20, help="episodes per maze")
    parser.add_argument("--seed", type=int, default=2022, help="seed of the maze set")
    args = parser.parse_args()
    torch.set_num_threads(1)  # small batched steps: one thread is fastest, and the machine is shared

    agents = args.agent or ["rllib:ppo_maze", "builtin:random", "builtin:wall_follower"] + (
        [f"dcd:{ACCEL}"] if ACCEL.is_file() else [])
    levels = random_valid_levels(args.mazes, seed=args.seed)
    optimal = np.array([lv.optimal_path_length for lv in levels])
    walls = np.array([lv.num_walls for lv in levels])
    print(f"{args.mazes} random valid 16x16 mazes (seed {args.seed}): walls mean {walls.mean():.1f} "
          f"[{walls.min()}, {walls.max()}], optimal path mean {optimal.mean():.1f} [{optimal.min()}, {optimal.max()}]; "
          f"{args.episodes} episodes per maze, max 648 steps")
    print()
    print(f"| agent | success rate | mean path length | mazes solved every episode | s per maze |")
    print(f"|---|---|---|---|---|")
    for spec in agents:
        agent = load_maze_agent(spec)
        started = time.perf_counter()
        results = [evaluate(level, agent, episodes=args.episodes, seed=i) for i, level in enumerate(levels)]
        per_maze = (time.perf_counter() - started) / len(levels)
        success = np.mean([r.success_rate for r in results])
        path = np.mean([r.mean_path_length for r in results])
        solved = sum(r.success_rate == 1.0 for r in results)
        name = f"dcd:../shared/models/accel_seed_1/model_20000.tar (ACCEL)" if spec == f"dcd:{ACCEL}" else spec
        print(f"| `{name}` | {success:.3f} | {path:.1f} | {solved}/{len(levels)} | {per_maze:.2f} |", flush=True)


if __name__ == "__main__":
    main()
