"""Simulator pool throughput (1 vs 2 actors) and per-task overhead vs evaluating in-process.

    python benchmarks/bench_pool.py [--preset cpu] [--n 64] [--repeats 2]

Same Maze solutions and seeds for every evaluator, in the same run. Targets (issue 4): 2 actors
≥ 1.7× the throughput of 1 on this 2-core machine; the pool's per-task overhead ≤ 5% of an
in-process evaluation at Maze batch sizes. Actor start-up and agent loading are excluded (each
pool is warmed up first): they are paid once per trial, not per batch.

The machine's load average is printed before and after: on a shared machine other processes
take cores from the actors, which lowers the 2-actor speed-up and inflates the overhead.
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np


def timed(evaluate, solutions, seeds, repeats: int) -> float:
    """Best of ``repeats`` wall-clock seconds (the least-disturbed run on a shared machine)."""
    best = float("inf")
    for _ in range(repeats):
        started = time.perf_counter()
        evaluate(solutions, seeds)
        best = min(best, time.perf_counter() - started)
    return best


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--preset", default="cpu", help="Maze preset (sets episodes per evaluation)")
    parser.add_argument("--n", type=int, default=64, help="solutions per batch")
    parser.add_argument("--repeats", type=int, default=2)
    parser.add_argument("--chunk-size", type=int, default=1)
    args = parser.parse_args()

    os.environ.setdefault("RAY_AUTH_MODE", "disabled")
    import ray
    import torch

    from dsage_ray.config import RunConfig
    from dsage_ray.core.evaluation import InProcessEvaluator
    from dsage_ray.domains import build_domain
    from dsage_ray.ray.pool import SimulatorPool

    torch.set_num_threads(1)  # like one actor: a fair in-process baseline
    config = RunConfig.build({"domain": "maze", "preset": args.preset})
    domain = build_domain(config)
    solutions = domain.random_solutions(args.n, np.random.default_rng(0))
    seeds = list(range(args.n))
    print(f"load average before: {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores")
    print(f"maze, agent {config.maze.agent}, {config.maze.episodes} episodes per evaluation, batch {args.n}")

    in_process = InProcessEvaluator(domain=domain)
    in_process(solutions[:2], seeds[:2])  # warm-up (lazy imports, caches)
    t_local = timed(in_process, solutions, seeds, args.repeats)
    print(f"in-process          {t_local:7.2f} s   {args.n / t_local:7.1f} evals/s   "
          f"{1000 * t_local / args.n:6.1f} ms/eval")

    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    times = {}
    for workers in (1, 2):
        with SimulatorPool(config=config, num_workers=workers, cpus_per_worker=1.0,
                           chunk_size=args.chunk_size) as pool:
            pool(solutions[:2 * workers], seeds[:2 * workers])  # warm-up: actors up, agent loaded
            times[workers] = timed(pool, solutions, seeds, args.repeats)
        print(f"pool, {workers} actor{'s' if workers > 1 else ' '}     {times[workers]:7.2f} s   "
              f"{args.n / times[workers]:7.1f} evals/s")
    ray.shutdown()

    speedup = times[1] / times[2]
    overhead = (times[1] - t_local) / t_local
    print(f"speed-up 2 vs 1 actor: {speedup:.2f}x   (target >= 1.7x)")
    print(f"per-task overhead, 1 actor vs in-process: {100 * overhead:+.1f}%   "
          f"({1000 * (times[1] - t_local) / args.n:+.2f} ms/task; target <= 5%)")
    print(f"load average after: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
