"""Whole outer-iteration time of the Maze ``cpu`` preset, split by phase.

    python benchmarks/bench_outer_iteration.py [--iterations 3] [--threads 2]

Runs DSAGE in-process (no Ray) with ``builtin:wall_follower`` and prints, for the first outer
iterations after the random one, the seconds spent training the surrogate, in the inner loop
(``qd.exploit_iterations`` × 150 surrogate predictions plus pyribs), selecting and evaluating.
"""

from __future__ import annotations

import argparse
import os

import torch

from dsage_ray.config import RunConfig
from dsage_ray.core.runner import DSAGE

PHASES = ("train", "exploit", "select", "evaluate", "total")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--iterations", type=int, default=3, help="outer iterations after the random one")
    parser.add_argument("--threads", type=int, default=2, help="torch threads")
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    config = RunConfig.build(preset="cpu", variant="dsage", name="bench_outer_iteration")
    print(f"maze cpu preset: {config.qd.exploit_iterations} inner iterations x "
          f"{config.qd.num_emitters * config.qd.batch_size} predictions, {config.surrogate.epochs} epochs, "
          f"torch threads {args.threads}, load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs")
    runner = DSAGE(config=config)
    first = runner.step()
    print(f"iteration 1 (random, {int(first['evals'])} evaluations): {first['time_total']:.1f} s")
    print("iteration  evals  picked  " + "  ".join(f"{p:>9}" for p in PHASES))
    for _ in range(args.iterations):
        m = runner.step()
        print(f"{int(m['outer_iteration']):9d}  {int(m['evals']):5d}  {int(m['evaluated_this_iteration']):6d}  "
              + "  ".join(f"{m.get('time_' + p, 0.0):8.1f}s" for p in PHASES))


if __name__ == "__main__":
    main()
