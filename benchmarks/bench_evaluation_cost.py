"""What a real evaluation costs, as a function of one of its measures: the fit behind a domain's ``evaluation_cost``.

Evaluates ``--levels`` elites of a finished run's archive in this process, one at a time, and fits the CPU
seconds each took as ``a + b · measure`` (least squares); ``--measure`` may also name one of the domain's
work counts (Maze ``steps``, Mario ``search_iterations``). A domain's ``evaluation_cost`` (measure, offset)
models an evaluation's cost as ``offset + measure``, so the offset to set is ``a / b``: the cost of the fixed
part of an evaluation (building the level, resetting the environment) in the measure's units. Elites are drawn
uniformly over the archive, so the whole range of the measure is covered.

Also printed: the correlation, the mean seconds per band of the measure, and how far the fit is off.

Usage:
    python benchmarks/bench_evaluation_cost.py RUN_FOLDER [--measure mean_path_length] [--levels 120] [--seed 0]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run", type=Path, help="a finished run folder (config.json, checkpoint.dsage)")
    parser.add_argument("--measure", default="mean_path_length", help="the measure (or work count) the cost grows with")
    parser.add_argument("--levels", type=int, default=120, help="elites to evaluate")
    parser.add_argument("--seed", type=int, default=0, help="which elites, and the evaluation seeds")
    args = parser.parse_args(argv)

    import torch
    from tqdm import tqdm

    from dsage_ray.config import RunConfig
    from dsage_ray.core.checkpoint import CHECKPOINT_NAME, load_checkpoint
    from dsage_ray.domains import build_domain
    from dsage_ray.types import WorkCountingDomain

    torch.set_num_threads(1)
    config = RunConfig.from_file(args.run / "config.json")
    domain = build_domain(config)
    names = list(domain.measure_names)
    counts = list(domain.work_names) if isinstance(domain, WorkCountingDomain) else []
    if args.measure not in names + counts:
        parser.error(f"--measure {args.measure!r} is neither one of the run's measures {names} nor one of its "
                     f"work counts {counts}")
    solutions = load_checkpoint(args.run / CHECKPOINT_NAME)["archive"].data("solution")
    rng = np.random.default_rng(args.seed)
    rows = rng.choice(len(solutions), size=min(args.levels, len(solutions)), replace=False)
    candidates: dict[str, list[float]] = {name: [] for name in names + counts}
    seconds = []
    for i, row in enumerate(tqdm(rows, desc="evaluate", unit="level")):
        tic = time.process_time()
        result = domain.evaluate(solutions[row], int(args.seed * 100_000 + i))
        seconds.append(time.process_time() - tic)
        values = dict(zip(names, result.measures.tolist())) | (domain.work_counts(result) if counts else {})
        for name in candidates:
            candidates[name].append(float(values[name]))
    seconds = np.array(seconds)
    measure = np.array(candidates[args.measure])
    slope, intercept = np.polyfit(measure, seconds, 1)
    residual = seconds - (intercept + slope * measure)
    print(f"{len(rows)} elites of {args.run} evaluated in this process ({config.domain}, agent "
          f"{getattr(domain, 'agent_spec', '?')}), CPU seconds per evaluation against {args.measure}:")
    edges = np.quantile(measure, np.linspace(0, 1, 6))
    for lo, hi in zip(edges[:-1], edges[1:]):
        band = (measure >= lo) & (measure <= hi)
        print(f"  {args.measure} {lo:7.1f} – {hi:7.1f}: {seconds[band].mean():.3f} s ({band.sum()} levels)")
    print(f"correlation {np.corrcoef(measure, seconds)[0, 1]:.3f}; fit seconds = {intercept:.4f} + {slope:.6f} · "
          f"{args.measure}; residual s.d. {residual.std():.3f} s")
    print(f"evaluation_cost offset = {intercept / slope:.1f} (measure {args.measure})")
    print("correlation of the CPU seconds with each measure and work count: " + ", ".join(
        f"{name} {np.corrcoef(values, seconds)[0, 1]:.3f}" if np.std(values) > 0 else f"{name} (constant)"
        for name, values in candidates.items()))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
