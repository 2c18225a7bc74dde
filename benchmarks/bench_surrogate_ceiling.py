"""How well could any surrogate predict the Maze agent's path length from a run's data? Three reference points.

For a finished Maze DSAGE run (its checkpoint holds every evaluated level with the agent's real
measures, and its held-out levels) this prints, for the last measure (``mean_path_length``):

1. **The agent against itself**: every held-out level, and a random sample of the run's own levels,
   evaluated again with other seeds (same episodes). Spearman ρ and MAE between the two evaluations
   bound what a predictor of the measured value can reach: if they are high, the measure is a
   property of the level, not of the episodes' luck.
2. **A learning curve**: the run's surrogate setting (or ``--set`` overrides) trained from scratch on
   N = 200 … all-but-400 of the run's levels and scored on the same 400 levels it never saw, drawn from
   the same distribution (in-distribution ρ and MAE), and on the held-out levels. Flat in N means
   more of the same data will not help at this scale.
3. **One hand-made feature**: the Spearman ρ of the level's optimal (shortest-path) length with the
   agent's path length, in-distribution and on the held-out levels, and how the wall counts of the run's
   levels and of the held-out levels differ (the held-out generator draws densities 0-0.5; DSAGE
   searches where walls are many).

    python benchmarks/bench_surrogate_ceiling.py RUN_FOLDER [--set surrogate.epochs=30] [--retest 300]
"""

from __future__ import annotations

import argparse
from pathlib import Path


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("run", type=Path, help="a finished Maze run folder (holding its checkpoint)")
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                        help="training setting for the learning curve (default: the run's, 30 epochs)")
    parser.add_argument("--retest", type=int, default=300, help="run levels evaluated again")
    parser.add_argument("--test", type=int, default=400, help="in-distribution test levels of the learning curve")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)

    import numpy as np
    import torch
    from scipy import stats

    from dsage_ray.config import RunConfig, parse_override
    from dsage_ray.core.checkpoint import CHECKPOINT_NAME, load_checkpoint
    from dsage_ray.domains import build_domain
    from dsage_ray.domains.maze.encoding import WALL
    from dsage_ray.surrogate import Surrogate, SurrogateDataset
    from dsage_ray.surrogate.models import pad_to_power_of_two

    torch.set_num_threads(1)
    state = load_checkpoint(args.run / CHECKPOINT_NAME)
    config = RunConfig.build(state["config"])
    if config.domain != "maze" or state.get("dataset") is None or not state.get("holdout"):
        raise SystemExit(f"{args.run}: needs a Maze surrogate run with held-out levels (surrogate.holdout_levels > 0)")
    setting = RunConfig.build({**config.to_flat(), "surrogate.epochs": 30,
                               **dict(parse_override(item) for item in args.overrides)})
    domain = build_domain(setting)
    names = domain.measure_names
    m = len(names) - 1
    stored = SurrogateDataset(level_shape=tuple(state["dataset"]["level_shape"]), num_measures=len(names),
                              occupancy_shape=domain.occupancy_shape)
    stored.load_state_dict(state["dataset"])
    rows = stored.levels()
    run_solutions = rows[:, WALL, :domain.height, :domain.width].reshape(len(rows), -1).astype(domain.solution_dtype)
    run_values = stored.measures[:, m]
    held_solutions = np.asarray(state["holdout"]["solutions"])
    held_values = np.array([r.measures[m] for r in state["holdout"]["results"]])

    def rho(a, b) -> float:
        return float(stats.spearmanr(a, b).statistic)

    def line(label: str, predicted, actual) -> str:
        return f"{label}: Spearman ρ {rho(predicted, actual):.3f}, MAE {np.abs(predicted - actual).mean():.1f}"

    print(f"run {args.run}: {len(rows)} evaluated levels, {len(held_values)} held-out levels, measure {names[m]} "
          f"(agent {config.maze.agent}, {config.maze.episodes} episodes)")
    # 1. The agent against itself, with seeds no run uses for these levels.
    rng = np.random.default_rng(args.seed)
    sample = np.sort(rng.choice(len(rows), size=min(args.retest, len(rows)), replace=False))
    again_held = np.array([domain.evaluate(s, seed=1_000_003 + i).measures[m] for i, s in enumerate(held_solutions)])
    again_run = np.array([domain.evaluate(run_solutions[i], seed=2_000_003 + int(i)).measures[m] for i in sample])
    print("1. the agent evaluated again (other seeds):")
    print("   " + line(f"held-out levels ({len(held_values)})", again_held, held_values))
    print("   " + line(f"run levels ({len(sample)})", again_run, run_values[sample]))

    # 2. Learning curve of the surrogate setting, trained from scratch on growing subsets.
    def encode(solutions):
        return pad_to_power_of_two(domain.encode(solutions), pad_channel=domain.encoding_pad_channel)

    levels, held_levels = encode(run_solutions), encode(held_solutions)
    order = rng.permutation(len(levels))
    test, pool = order[:args.test], order[args.test:]
    sizes = sorted({n for n in (200, 400, 800, 1600) if n < len(pool)} | {len(pool)})
    print(f"2. learning curve: {setting.surrogate.kind}, {setting.surrogate.epochs} epochs, batch "
          f"{setting.surrogate.batch_size}, path channels {setting.maze.path_channels}; "
          f"{len(test)} in-distribution test levels")
    for n in sizes:
        train = np.sort(pool[:n])
        surrogate = Surrogate(kind=setting.surrogate.kind, input_channels=levels.shape[1],
                              input_shape=tuple(levels.shape[2:]), occupancy_shape=domain.occupancy_shape,
                              num_measures=len(names), config=setting.surrogate, seed=args.seed,
                              measure_ranges=domain.measure_ranges, measure_names=names)
        dataset = surrogate.make_dataset()
        dataset.load_state_dict({"levels": np.packbits(levels[train].reshape(n, -1).astype(bool), axis=1),
                                 "objective": stored.objective[train], "measures": stored.measures[train],
                                 "occupancy": stored.occupancy[train], "level_shape": levels.shape[1:]})
        surrogate.train(dataset)
        fit = surrogate.predict(levels[train]).measures[:, m]
        print(f"   N={n:>5}  " + line("training levels", fit, run_values[train]) + " | "
              + line("test levels", surrogate.predict(levels[test]).measures[:, m], run_values[test]) + " | "
              + line("held-out", surrogate.predict(held_levels).measures[:, m], held_values), flush=True)

    # 3. One feature, and the two distributions.
    def optimal(solutions):
        return np.array([domain.level(s).optimal_path_length for s in solutions])

    def walls(solutions):
        return np.asarray(solutions).reshape(len(solutions), -1).sum(axis=1)

    print("3. optimal path length as the predictor (rank only):")
    print(f"   run levels: Spearman ρ {rho(optimal(run_solutions), run_values):.3f}; "
          f"held-out levels: Spearman ρ {rho(optimal(held_solutions), held_values):.3f}")
    for label, solutions in (("run levels", run_solutions), ("held-out levels", held_solutions)):
        low, mid, high = np.percentile(walls(solutions), [5, 50, 95])
        print(f"   walls of the {label}: 5th/50th/95th percentile {low:.0f}/{mid:.0f}/{high:.0f}")


if __name__ == "__main__":
    main()
