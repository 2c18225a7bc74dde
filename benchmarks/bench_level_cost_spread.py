"""Per-level evaluation seconds of DSAGE's random first iteration (and, with ``picks``, of its first surrogate picks).

Whether a domain's surrogate picks will be slow to play cannot be read from the random levels alone: their seconds
averaged per archive cell (as DSAGE's downsampled picks spread over cells) are within 1.2x of their plain mean on the
Maze and on Mario alike, while Mario's picks then cost about 5x a random level and the Maze's about 1x
(docs/results/equal_compute §22). One line per phase: level mean, cell-uniform mean and their ratio, the slowest
quarter's mean and the maximum over the mean; CPU seconds of this process::

    python benchmarks/bench_level_cost_spread.py maze 7 picks
    LD_PRELOAD=$JAVA_HOME/lib/libjsig.so python benchmarks/bench_level_cost_spread.py mario 7
    python benchmarks/bench_level_cost_spread.py cartpole 7 picks     # or lunar
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np

from dsage_ray.config import RunConfig
from dsage_ray.core.runner import DSAGE
from dsage_ray.domains import build_domain

GYM = {"cartpole": ("CartPole-v1", "cartpole", "rllib:ppo_cartpole"),
       "lunar": ("LunarLander-v3", "lunarlander", "rllib:ppo_lunarlander")}


def run_config(name: str, seed: int) -> RunConfig:
    """The ``cpu`` preset of the Maze or Mario, or the ``demo`` preset of a shipped gym audit."""
    if name in ("maze", "mario"):
        return RunConfig.from_file(f"experiments/configs/{name}_dsage.toml", {"preset": "cpu", "seed": seed})
    env, space, agent = GYM[name]
    return RunConfig.build({"domain": "gym", "preset": "demo", "gym.env": env, "gym.space": space, "gym.agent": agent,
                            "seed": seed})


def spread(run: DSAGE, entries: list[tuple[float, np.ndarray]]) -> dict[str, float]:
    """Level mean, cell-uniform mean (each archive cell the levels fall in weighs the same) and tail shares."""
    seconds = np.array([s for s, _ in entries])
    cells: dict[int, list[float]] = {}
    for cell, s in zip(run.archive.index_of(np.array([m for _, m in entries])), seconds):
        cells.setdefault(int(cell), []).append(float(s))
    mean = seconds.mean()
    cell_mean = np.mean([np.mean(v) for v in cells.values()])
    slowest = np.sort(seconds)[int(0.75 * len(seconds)):]
    return {"levels": len(seconds), "cells": len(cells), "level_mean_s": round(float(mean), 4),
            "cell_mean_s": round(float(cell_mean), 4), "cell_over_level": round(float(cell_mean / mean), 3),
            "slowest_quarter_over_mean": round(float(slowest.mean() / mean), 3),
            "max_over_mean": round(float(seconds.max() / mean), 3)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("domain", choices=["maze", "mario", *GYM])
    parser.add_argument("seed", type=int)
    parser.add_argument("picks", nargs="?", choices=["picks"], help="also the first surrogate iteration's picks")
    args = parser.parse_args()
    config = run_config(args.domain, args.seed)
    domain = build_domain(config)
    entries: list[tuple[float, np.ndarray]] = []
    evaluate = domain.evaluate

    def timed(solution, seed):
        tic = time.process_time()
        result = evaluate(solution, seed)
        entries.append((time.process_time() - tic, result.measures))
        return result

    domain.evaluate = timed
    run = DSAGE(config=config, domain=domain)
    run.step()
    random_levels = spread(run, entries)
    print(args.domain, args.seed, "random", json.dumps(random_levels), flush=True)
    if args.picks:
        entries.clear()
        row = run.step()
        picked = spread(run, entries)
        print(args.domain, args.seed, "picks", json.dumps(picked), "pick / random level:",
              round(picked["level_mean_s"] / random_levels["level_mean_s"], 3),
              f"train {row.get('time_train', 0):.1f} s, exploit {row.get('time_exploit', 0):.1f} s", flush=True)


if __name__ == "__main__":
    main()
