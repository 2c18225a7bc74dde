"""How well a few episodes of the agent predict its full evaluation, and what they cost (``selection.screen_episodes``).

    python benchmarks/bench_screen.py --data FILE.npz [--agent dcd:accel] [--episodes 1,2,4] [--levels 1000] \
        [--precision fp32,bf16]

For each episode count, the Maze domain's screen (every level stepped in one batch) is run on the first ``--levels``
levels of a dataset (``benchmarks/maze_dataset.py``), and its mean path length is scored against the dataset's:
Spearman ρ, MAE in steps and milliseconds per level. Beside them, on the same levels: the optimal path length's ρ,
and a full evaluation's milliseconds per level (``--full`` levels evaluated one at a time, as a run does), so that
the last lines print what a screened level costs as a share of an evaluation. With ``--precision fp32,bf16`` each
episode count is screened in both (``experimental.screen_precision``: bf16 plays the agent's reduced-precision copy,
where it has one). The dataset must hold the same agent's measurements (``maze_dataset.py from-run`` of a run of
that agent).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_surrogate_ceiling import spearman  # noqa: E402
from maze_dataset import PATH_LENGTH, load  # noqa: E402

from dsage_ray.core.threads import torch_threads  # noqa: E402
from dsage_ray.domains.maze.domain import MazeDomain  # noqa: E402
from dsage_ray.domains.maze.plugin import MazeConfig  # noqa: E402


def main(argv: list[str] | None = None) -> dict[str, dict[str, float]]:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--data", required=True, help="a Maze dataset (.npz) of this agent's evaluations")
    parser.add_argument("--agent", default="dcd:accel", help="the agent the dataset measured (default dcd:accel)")
    parser.add_argument("--episodes", default="1,2,4", help="comma-separated screen episode counts")
    parser.add_argument("--levels", type=int, default=1000, help="levels screened (the dataset's first)")
    parser.add_argument("--full", type=int, default=100, help="levels given a full evaluation, for its cost")
    parser.add_argument("--full-episodes", type=int, default=50, help="episodes of a full evaluation")
    parser.add_argument("--precision", default="fp32",
                        help="comma-separated screen precisions, fp32 and/or bf16 (experimental.screen_precision)")
    parser.add_argument("--seed", type=int, default=1000)
    args = parser.parse_args(argv)

    data = load(args.data)
    count = min(args.levels, len(data.walls))
    height, width = data.shape
    solutions = data.solutions()[:count]
    truth = data.measures[:count, data.measure()].astype(np.float64)
    domain = MazeDomain(config=MazeConfig(height=int(height), width=int(width), agent=args.agent,
                                          episodes=args.full_episodes))
    levels = [domain.level(solution) for solution in solutions]
    valid = np.array([level.valid for level in levels])
    optimal = np.array([level.optimal_path_length for level in levels], dtype=np.float64)
    print(f"{count} levels of {args.data} ({int(valid.sum())} valid), agent {args.agent}; {PATH_LENGTH} "
          f"{truth[valid].mean():.1f} on average")
    print(f"optimal path length: Spearman ρ {spearman(optimal[valid], truth[valid]):.3f}")
    out: dict[str, dict[str, float]] = {}
    with torch_threads(1):
        precisions = args.precision.split(",")
        for precision in precisions:  # loads the agents before any timing
            domain.screen(solutions[:8], episodes=1, seed=0, precision=precision)
        for episodes in (int(k) for k in args.episodes.split(",")):
            for precision in precisions:
                tic = time.perf_counter()
                results = domain.screen(solutions, episodes=episodes, seed=args.seed, precision=precision)
                seconds = time.perf_counter() - tic
                screened = np.array([result.info.get(PATH_LENGTH, 0.0) for result in results])
                name = f"screen_{episodes}" + ("" if precision == "fp32" else f"_{precision}")
                out[name] = row = {
                    "rho": spearman(screened[valid], truth[valid]),
                    "mae": float(np.abs(screened[valid] - truth[valid]).mean()),
                    "ms_per_level": 1000 * seconds / count}
                print(f"screen, {episodes} episode(s), {precision}: Spearman ρ {row['rho']:.3f}, MAE "
                      f"{row['mae']:.1f} steps, {row['ms_per_level']:.2f} ms per level")
        full = min(args.full, count)
        tic = time.perf_counter()
        for i in range(full):
            domain.evaluate(solutions[i], seed=args.seed + i)
        out["full"] = {"ms_per_level": 1000 * (time.perf_counter() - tic) / max(full, 1)}
    if data.retest is not None:
        retest = data.retest[:count, data.measure()]
        both = valid & ~np.isnan(retest)
        if both.sum() > 2:
            print(f"the agent against itself ({int(both.sum())} levels evaluated twice): Spearman ρ "
                  f"{spearman(retest[both], truth[both]):.3f}")
    print(f"a full evaluation ({args.full_episodes} episodes, one level at a time, {full} levels): "
          f"{out['full']['ms_per_level']:.1f} ms per level")
    for name, row in out.items():
        if name != "full":
            print(f"{name}: a screened level costs {row['ms_per_level'] / out['full']['ms_per_level']:.1%} of an "
                  "evaluation")
    return out


if __name__ == "__main__":
    main()
