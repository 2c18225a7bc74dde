"""The best ``--search auto`` could do on a domain: a run that switches to the direct search right after the random
first iteration, before the surrogate ever trains.

``search = "auto"`` decides once the surrogate's first picks are probed (``dsage_ray.core.auto_search``): on Mario
that is after DSAGE's random levels, one training, one inner loop and a few picks, minutes of a 10-minute run. A rule
that decided from the random iteration alone could at best do what this run does: the same random levels, then the
direct search on the same archive for the rest of the time. Compare it with the direct search from the start (the
better fixed choice on Mario) to see whether any such rule could come within 5% of it::

    LD_PRELOAD=$JAVA_HOME/lib/libjsig.so python benchmarks/bench_auto_switch_bound.py \\
        --config experiments/configs/mario_dsage.toml --preset cpu --time-budget 600 --seed 90 --out RUNS/bound/switch_s90
    python benchmarks/bench_equal_compute.py RUNS/bound/{switch,cma_me}_s9{0,1,2} --baseline cma_me --clock cpu

The run folder is written as ``dsage-ray run`` writes one (``metrics.json``, ``archive.csv``), for
``bench_equal_compute.py`` to read beside runs of ``experiments/equal_compute.py``.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

from dsage_ray.config import RunConfig
from dsage_ray.core.auto_search import SearchChoice, direct_variant
from dsage_ray.core.runner import DSAGE


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--config", type=Path, required=True)
    parser.add_argument("--preset", default="cpu")
    parser.add_argument("--seed", type=int, required=True)
    parser.add_argument("--time-budget", type=float, required=True, help="seconds")
    parser.add_argument("--budget", type=int, default=100_000, help="evaluations (more than the time allows)")
    parser.add_argument("--out", type=Path, required=True)
    args = parser.parse_args(argv)

    config = RunConfig.from_file(args.config, {"preset": args.preset, "seed": args.seed, "budget": args.budget,
                                               "time_budget": args.time_budget, "search": "auto",
                                               "name": "switch"})
    run = DSAGE(config=config)
    run.step()  # the random first iteration, as every DSAGE run and auto run begins
    # No look and no probe: their numbers are not measured here (NaN in the choice's metrics).
    run.proposer.continue_direct(SearchChoice(direct=True, variant=direct_variant(config), cost_ratio=math.nan,
                                              random_level_seconds=math.nan, surrogate_level_seconds=math.nan))
    run.run()
    args.out.mkdir(parents=True, exist_ok=True)
    run.write_outputs(args.out)
    last = run.history[-1]
    print(f"{args.out}: {run.evals} evaluations, QD-score {last['qd_score']:.1f}, "
          f"{last['cpu_time']:.0f} CPU s, switched to {direct_variant(config)} after {run.history[0]['evals']:.0f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
