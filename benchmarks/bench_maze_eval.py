"""Time of one 50-episode Maze evaluation with the ACCEL agent on one core: evaluate() vs a MiniGrid-stepped loop.

Both loops run the same agent with the same batched policy calls (one call per step over the running episodes;
finished episodes leave the batch), the same initial headings and the same rng, so they play identical episodes
(checked); they differ only in what steps the episodes: :func:`~dsage_ray.domains.maze.evaluate.evaluate` uses
the batched simulator, the reference steps one MiniGrid ``MazeEnv`` per episode. Mazes are the fixed set of
random valid 16×16 mazes of ``bench_maze_simulator.py``. Torch runs on one thread. CPU time of this process
(``time.process_time``) is the one-core figure on a shared machine; wall time is printed with the load average.
Target: mean ≤ 0.5 s per maze (the paper: 3.5 s on its hardware).

Without the ACCEL checkpoint (``$DSAGE_SHARED_DIR``, else ``../shared`` beside the repo) the ACCEL figures are
skipped and ``builtin:wall_follower`` times the simulator/evaluation part alone.

Run: ``.venv/bin/python benchmarks/bench_maze_eval.py [--mazes N] [--agent SPEC]``
"""

from __future__ import annotations

import argparse
import os
import pathlib
import time

import numpy as np
import torch
from bench_maze_simulator import DENSITY_RANGE  # this script's folder is on sys.path when run

from dsage_ray.domains.maze.agents import load_maze_agent
from dsage_ray.domains.maze.env import minigrid_evaluate
from dsage_ray.domains.maze.evaluate import evaluate
from dsage_ray.domains.maze.generator import random_valid_levels

EPISODES = 50
TARGET_S = 0.5
FALLBACK_AGENT = "builtin:wall_follower"
REPO_ROOT = pathlib.Path(__file__).resolve().parents[1]


def accel_checkpoint() -> pathlib.Path:
    shared = pathlib.Path(os.environ.get("DSAGE_SHARED_DIR", REPO_ROOT.parent / "shared"))
    return shared / "models" / "accel_seed_1" / "model_20000.tar"


def timed(fn, *args, **kwargs):
    cpu, wall = time.process_time(), time.perf_counter()
    out = fn(*args, **kwargs)
    return out, time.process_time() - cpu, time.perf_counter() - wall


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--mazes", type=int, default=20, help="random valid 16x16 mazes (default 20)")
    parser.add_argument("--agent", default=None, help="agent spec (default: the ACCEL checkpoint, else the fallback)")
    args = parser.parse_args()
    torch.set_num_threads(1)

    spec = args.agent
    if spec is None:
        checkpoint = accel_checkpoint()
        if checkpoint.is_file():
            spec = f"dcd:{checkpoint}"
        else:
            spec = FALLBACK_AGENT
            print(f"SKIP ACCEL figures: checkpoint not found at {checkpoint} (set DSAGE_SHARED_DIR); "
                  f"timing {FALLBACK_AGENT} instead (simulator and evaluation loop, no network)")
    agent = load_maze_agent(spec)
    levels = random_valid_levels(args.mazes, seed=0, density_range=DENSITY_RANGE)
    evaluate(levels[0], agent, episodes=EPISODES)  # warm-up (imports, caches)
    minigrid_evaluate(levels[0], agent, episodes=2, seed=0)

    load_before = os.getloadavg()
    sim, ref, env_steps = np.zeros((2, args.mazes)), np.zeros((2, args.mazes)), 0
    for i, level in enumerate(levels):  # interleaved, so both loops see the same machine load
        result, sim[0, i], sim[1, i] = timed(evaluate, level, agent, episodes=EPISODES, seed=i)
        (lengths, successes, _), ref[0, i], ref[1, i] = timed(minigrid_evaluate, level, agent, episodes=EPISODES, seed=i)
        if not (np.array_equal(lengths, result.episode_lengths) and np.array_equal(successes, result.successes)):
            raise SystemExit(f"maze {i}: the MiniGrid loop played different episodes from evaluate()")
        env_steps += int(lengths.sum())
    load_after = os.getloadavg()

    print(f"agent: {spec}")
    print(f"{args.mazes} random valid 16x16 mazes x {EPISODES} episodes, torch threads {torch.get_num_threads()}, "
          f"{env_steps / args.mazes:,.0f} env-steps per maze (identical episodes in both loops: checked)")
    print(f"load average (1/5/15 min) before {'/'.join(f'{x:.1f}' for x in load_before)}, "
          f"after {'/'.join(f'{x:.1f}' for x in load_after)}, on {os.cpu_count()} CPUs")
    print(f"evaluate() (batched simulator): mean {sim[0].mean():.3f} s CPU  {sim[1].mean():.3f} s wall per maze "
          f"(CPU max {sim[0].max():.3f} s)")
    print(f"MiniGrid-stepped reference    : mean {ref[0].mean():.3f} s CPU  {ref[1].mean():.3f} s wall per maze "
          f"(CPU max {ref[0].max():.3f} s)")
    print(f"ratio (reference / evaluate): {ref[0].mean() / sim[0].mean():.1f}x CPU, {ref[1].mean() / sim[1].mean():.1f}x wall")
    if spec.startswith("dcd:"):
        verdict = "met" if sim[0].mean() <= TARGET_S else "NOT met"
    else:
        verdict = "n/a (the target is for the ACCEL agent)"
    print(f"target mean <= {TARGET_S} s per maze on one core (CPU time): {verdict}")


if __name__ == "__main__":
    main()
