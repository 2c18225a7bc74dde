"""Do mutants of a search's best elites do as badly as their parents? The evidence behind ``selection.elite_mutants``.

Reads the ground-truth archive of a finished run or audit search folder (its ``checkpoint.dsage``), draws
``--levels`` parents from each of three pools of its elites, mutates each once with the run's own operator
(``qd.mutation_cells`` cells of a Maze bitmap, Gaussian ``qd.sigma0`` noise on a latent), evaluates the mutants
with the run's agent in this process, and prints one line per pool:

- ``best``: the elites tied at the archive's best objective (an audit's never-solved levels);
- ``top share``: the run's ``experimental.elite_share`` of the elites by objective, the parents of ``elite_mutants``;
- ``uniform``: every elite (MAP-Elites' parents).

Each line gives the mutants' mean objective, the share that reach the archive's best objective, the share at or
above the midpoint of its objective range, the share in a cell the archive does not hold yet, and CPU seconds per
evaluation (mutants of never-solved mazes play to the step limit, so they cost more).

Usage:
    python benchmarks/bench_elite_mutants.py AUDIT/search --levels 200
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run", type=Path, help="a finished run or audit search folder (checkpoint.dsage)")
    parser.add_argument("--levels", type=int, default=200, help="mutants per pool (default 200)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the parents, mutations and episodes")
    args = parser.parse_args(argv)
    if args.levels < 1:
        parser.error("--levels must be positive")

    from dsage_ray.config import RunConfig
    from dsage_ray.core.checkpoint import CHECKPOINT_NAME, load_checkpoint
    from dsage_ray.core.evaluation import InProcessEvaluator, evaluate_with_retry
    from dsage_ray.domains import build_domain
    from dsage_ray.errors import InputError
    from dsage_ray.qd.mutants import best_elites, mutate

    path = args.run / CHECKPOINT_NAME
    if not path.is_file():
        raise SystemExit(f"{args.run}: no {CHECKPOINT_NAME} (a finished run or audit search folder holds one)")
    state = load_checkpoint(path)
    config = RunConfig.build(state["config"])
    archive = state["archive"]
    if archive.empty:
        raise SystemExit(f"{args.run}: its archive is empty")
    data = archive.data(["solution", "objective", "index"])
    objective = np.asarray(data["objective"], np.float64)
    held = set(np.asarray(data["index"]).tolist())
    best, middle = objective.max(), (objective.min() + objective.max()) / 2
    pools = {"best": np.flatnonzero(objective >= best),
             "top share": best_elites(archive, share=config.experimental.elite_share),
             "uniform": np.arange(len(objective))}
    domain = build_domain(config)
    evaluator = InProcessEvaluator(domain=domain, threads=config.torch_threads)
    rng = np.random.default_rng(args.seed)
    print(f"{args.run}: {len(objective)} elites, best objective {best:g} ({len(pools['best'])} elites), "
          f"top share {config.experimental.elite_share:g} ({len(pools['top share'])} elites); "
          f"{args.levels} mutants per pool, {config.qd.emitter} mutation")
    for offset, (name, pool) in enumerate(pools.items()):
        try:
            mutants = mutate(np.asarray(data["solution"])[rng.choice(pool, size=args.levels)], qd=config.qd, rng=rng)
        except ValueError as exc:
            raise InputError(f"{args.run}: {exc}") from None
        seeds = [args.seed * 1_000_003 + offset * args.levels + k for k in range(args.levels)]
        tic = time.process_time()
        results = [r for r in evaluate_with_retry(evaluator, mutants, seeds) if not r.failed]
        seconds = (time.process_time() - tic) / max(len(results), 1)
        if not results:
            print(f"{name:>9}: every evaluation failed")
            continue
        values = np.array([r.objective for r in results], np.float64)
        cells = archive.index_of(np.array([r.measures for r in results], np.float64))
        new = np.mean([int(c) not in held for c in cells])
        print(f"{name:>9}: {len(results)} mutants, mean objective {values.mean():.3f}, "
              f"{np.mean(values >= best):.0%} at the best ({best:g}), {np.mean(values >= middle):.0%} at or above "
              f"{middle:g}, {new:.0%} in a new cell, {seconds:.3f} CPU s per evaluation")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
