"""Simulator pool throughput (1 vs 2 actors) and per-task overhead vs evaluating in-process.

    python benchmarks/bench_pool.py [--preset cpu] [--n 200] [--repeats 5]

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


def interleaved(evaluators: dict, solutions, seeds, rounds: int) -> dict[str, float]:
    """Median wall-clock seconds per evaluator, measured in alternating rounds.

    Alternating means a change in the machine's load (other users) hits every evaluator alike
    instead of whichever happened to run during it.
    """
    times: dict[str, list[float]] = {name: [] for name in evaluators}
    for _ in range(rounds):
        for name, evaluate in evaluators.items():
            started = time.perf_counter()
            evaluate(solutions, seeds)
            times[name].append(time.perf_counter() - started)
    return {name: float(np.median(values)) for name, values in times.items()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--preset", default="cpu", help="Maze preset (sets episodes per evaluation)")
    parser.add_argument("--n", type=int, default=200, help="solutions per batch")
    parser.add_argument("--repeats", type=int, default=5, help="alternating rounds (median)")
    parser.add_argument("--chunk-size", type=int, default=0, help="0: the pool's automatic chunking")
    args = parser.parse_args()

    import ray
    import torch

    from dsage_ray.config import RunConfig
    from dsage_ray.core.evaluation import InProcessEvaluator
    from dsage_ray.domains import build_domain
    from dsage_ray.ray.pool import SimulatorPool
    from dsage_ray.ray.session import start_ray

    torch.set_num_threads(1)  # like one actor: a fair in-process baseline
    config = RunConfig.build({"domain": "maze", "preset": args.preset})
    domain = build_domain(config)
    solutions = domain.random_solutions(args.n, np.random.default_rng(0))
    seeds = list(range(args.n))
    print(f"load average before: {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores")
    print(f"maze, agent {config.maze.agent}, {config.maze.episodes} episodes per evaluation, batch {args.n}")

    in_process = InProcessEvaluator(domain=domain)
    in_process(solutions[:2], seeds[:2])  # warm-up (lazy imports, caches)
    # 3 logical CPUs: both pools exist at once (1 + 2 actors, 1 CPU each) but only one works at a
    # time, so the 2-core machine is never asked for more than 2 busy processes.
    start_ray(num_cpus=3, log_to_driver=False)
    one = SimulatorPool(config=config, num_workers=1, cpus_per_worker=1.0, chunk_size=args.chunk_size)
    two = SimulatorPool(config=config, num_workers=2, cpus_per_worker=1.0, chunk_size=args.chunk_size)
    for pool in (one, two):
        pool(solutions[:4], seeds[:4])  # warm-up: actors up, agent loaded
    times = interleaved({"in-process": in_process, "pool, 1 actor": one, "pool, 2 actors": two},
                        solutions, seeds, args.repeats)
    one.close()
    two.close()
    ray.shutdown()
    for name, seconds in times.items():
        print(f"{name:<16} {seconds:7.2f} s   {args.n / seconds:7.1f} evals/s   {1000 * seconds / args.n:6.2f} ms/eval")
    t_local, times = times["in-process"], {1: times["pool, 1 actor"], 2: times["pool, 2 actors"]}

    speedup = times[1] / times[2]
    overhead = (times[1] - t_local) / t_local
    print(f"speed-up 2 vs 1 actor: {speedup:.2f}x   (target >= 1.7x)")
    print(f"per-task overhead, 1 actor vs in-process: {100 * overhead:+.1f}%   "
          f"({1000 * (times[1] - t_local) / args.n:+.2f} ms/task; target <= 5%)")
    print(f"load average after: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
