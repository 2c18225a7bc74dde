"""The paper's ablation grid (variant × seed), or a grid over any config keys, as one Ray Tune experiment.

    python experiments/ablation.py --preset tiny                  # 3 variants × 2 seeds, a few minutes on 2 cores
    python experiments/ablation.py --preset cpu --seeds 5          # the paper's Maze comparison, scaled for CPUs
    python experiments/ablation.py --preset cpu --grid surrogate.epochs=10,50 --grid seed=0,1,2   # DSAGE only
    python experiments/ablation.py --preset cpu --grid variant=dsage,dsage_basic --grid qd.exploit_iterations=100,300
    python experiments/ablation.py --preset tiny --api run         # same grid through tune.run
    python experiments/ablation.py --preset tiny --resume          # continue an interrupted experiment (Tuner.restore)
    python experiments/summarize.py tb_logs/ablation_maze_tiny     # the table and the comparison plot
    tensorboard --logdir tb_logs                                   # ray/tune/qd_score, heatmaps, Fig. 9 scatter

Each trial is one DSAGE run (a ``DSAGETrainable``) with its own simulator actors; one Tune
iteration is one outer iteration. Trials crash-restore from their last checkpoint
(``--max-failures``). Every grid point's config is checked before Ray starts. ``summarize.py``
groups the trials by every key that varies.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path


# Ray keys for the tiny preset: 1 CPU per trial (half for the trial, half for one simulator), so
# two trials run side by side on a 2-core machine.
TINY_RAY = {"ray.num_workers": 1, "ray.cpus_per_worker": 0.5, "ray.trial_cpus": 0.5}


def tiny_variants(domain: str) -> list[str]:
    """The smoke grid: DSAGE and the domain's own baselines from the paper's comparison, no DSAGE ablations."""
    from dsage_ray.config import COMMON_VARIANTS, paper_comparison

    return [v for v in paper_comparison(domain) if v == "dsage" or v not in COMMON_VARIANTS]


def parse_args() -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--domain", default="maze", help="a registered domain (maze, mario, a plug-in's)")
    parser.add_argument("--preset", default="tiny", choices=["tiny", "demo", "cpu", "paper"])
    parser.add_argument("--grid", action="append", default=[], metavar="KEY=V1,V2",
                        help="a grid axis over any config key, values read like --set values "
                             "(e.g. --grid surrogate.epochs=10,50 or --grid seed=0,1,2)")
    parser.add_argument("--variants", help="comma-separated (default: the paper's; for --preset tiny dsage and "
                                           "the domain's baselines; "
                                           "the --domain's dsage when --grid names other keys)")
    parser.add_argument("--seeds", type=int, default=None, help="seeds 0..K-1 (default: 2 for tiny, 5 otherwise)")
    parser.add_argument("--api", default="tuner", choices=["tuner", "run"], help="tune.Tuner or tune.run")
    parser.add_argument("--storage", default="tb_logs", help="storage folder (made absolute)")
    parser.add_argument("--name", help="experiment name (default: ablation_<domain>_<preset>)")
    parser.add_argument("--resume", action="store_true", help="continue the experiment of the same name")
    parser.add_argument("--max-failures", type=int, default=2, help="crash restores per trial")
    parser.add_argument("--workers", type=int, help="simulator actors per trial (ray.num_workers)")
    parser.add_argument("--address", help="Ray cluster to join (default: RAY_ADDRESS or a local cluster)")
    parser.add_argument("--num-cpus", type=int, help="logical CPUs of a local cluster (default: all)")
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                        help="any config key, e.g. --set budget=300")
    return parser.parse_args()


def main() -> int:
    args = parse_args()
    os.environ.setdefault("RAY_AUTH_MODE", "disabled")
    from dsage_ray.config import RunConfig, paper_comparison, parse_override
    from dsage_ray.config import ConfigError
    from dsage_ray.ray.experiment import (ExperimentInterrupted, ablation_axes, check_resources, connect,
                                          grid_configs, grid_param_space, run_experiment)

    # 1. The base config: domain + preset, the tiny preset's Ray sizing, then explicit overrides.
    values = {"domain": args.domain, "preset": args.preset}
    if args.preset == "tiny":
        values.update(TINY_RAY)
    if args.workers is not None:
        values["ray.num_workers"] = args.workers
    # 2. The grid: --grid axes, variants and seeds; every grid point is a full DSAGE run, checked now.
    try:
        values.update(dict(parse_override(item) for item in args.overrides))
        base = RunConfig.build(values)
        axes = ablation_axes(
            base, args.grid, variants=args.variants.split(",") if args.variants else None, seeds=args.seeds,
            default_variants=tiny_variants(base.domain) if args.preset == "tiny" else paper_comparison(base.domain),
            default_seeds=2 if args.preset == "tiny" else 5)
        param_space = grid_param_space(base, axes)
    except ConfigError as exc:
        print(f"ablation: error: {exc}", file=sys.stderr)
        return 2
    name = args.name or f"ablation_{args.domain}_{args.preset}"

    # 3. Ray: join or start a cluster, and fail now (not hang) if a trial can never be placed.
    connect(args.address, num_cpus=args.num_cpus)
    check_resources(*grid_configs(base, axes)[1])

    # 4. Run every trial to its evaluation budget (Tune stops a trial when it reports done=True).
    shape = " × ".join(f"{key} ({len(values)})" for key, values in axes.items())
    print(f"{name}: {shape} via {args.api}, storage {args.storage}")
    started = time.perf_counter()
    try:
        path = run_experiment(param_space, name=name, storage_path=args.storage, api=args.api,
                              resume=args.resume, max_failures=args.max_failures,
                              checkpoint_every=base.checkpoint_every)
    except ExperimentInterrupted as exc:
        print(f"interrupted: {exc}")
        return 130
    print(f"done in {time.perf_counter() - started:.0f}s: {path}")
    print(f"table: python {Path(__file__).with_name('summarize.py')} {path}")
    from dsage_ray.core.tensorboard_log import tensorboard_hint

    print(f"open it in TensorBoard: {tensorboard_hint(path)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
