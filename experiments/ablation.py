"""The paper's ablation grid (variant × seed), or a grid over any config keys, as one Ray Tune experiment.

    python experiments/ablation.py --preset tiny                  # 3 variants × 2 seeds, a few minutes on 2 cores
    python experiments/ablation.py --preset cpu --seeds 5          # the paper's Maze comparison, scaled for CPUs
    python experiments/ablation.py --preset cpu --grid surrogate.epochs=10,50 --grid seed=0,1,2   # DSAGE only
    python experiments/ablation.py --preset tiny --api run         # same grid through tune.run
    python experiments/ablation.py --preset tiny --resume          # continue an interrupted experiment
    python experiments/summarize.py tb_logs/ablation_maze_tiny     # the table and the comparison plot

This script is ``dsage-ray ablate`` (:func:`dsage_ray.ablate`) with defaults for a quick look: the
``tiny`` preset sized so that two trials share a 2-core machine, DSAGE against the domain's own
baselines, and an experiment named after the domain and preset. Each trial is one DSAGE run (a
``DSAGETrainable``) with its own simulator actors; one Tune iteration is one outer iteration.
"""

from __future__ import annotations

import argparse
import os
import sys
import time

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
    parser.add_argument("--preset", default="tiny", help="the domain's preset (tiny, demo, cpu, paper)")
    parser.add_argument("--grid", action="append", default=[], metavar="KEY=V1,V2",
                        help="a grid axis over any config key (e.g. --grid surrogate.epochs=10,50)")
    parser.add_argument("--variants", help="comma-separated (default: the paper's; for --preset tiny dsage and "
                                           "the domain's baselines)")
    parser.add_argument("--seeds", type=int, default=None, help="seeds 0..K-1 (default: 2 for tiny, 5 otherwise)")
    parser.add_argument("--api", default="tuner", choices=["tuner", "run"], help="tune.Tuner or tune.run")
    parser.add_argument("--storage", default="tb_logs",
                        help="storage folder, or a URI (s3://bucket/runs, file:///shared/runs)")
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
    import dsage_ray
    from dsage_ray.config import parse_override
    from dsage_ray.errors import DsageError, Interrupted

    # 1. The base config: domain + preset, the tiny preset's Ray sizing, then explicit overrides.
    tiny = args.preset == "tiny"
    overrides = {"domain": args.domain, "name": args.name or f"ablation_{args.domain}_{args.preset}",
                 **(TINY_RAY if tiny else {})}
    try:
        overrides.update(dict(parse_override(item) for item in args.overrides))
    except DsageError as exc:
        print(f"ablation: error: {exc}", file=sys.stderr)
        return 2
    variants = args.variants.split(",") if args.variants else None
    if variants is None and tiny and not args.grid:
        variants = tiny_variants(args.domain)
    seeds = args.seeds if args.seeds is not None else (2 if tiny else None)
    if args.num_cpus is not None and not (args.address or os.environ.get("RAY_ADDRESS")):
        from dsage_ray.ray.session import start_ray

        start_ray(None, num_cpus=args.num_cpus)

    # 2. Every grid point is checked, then each trial runs to its evaluation budget.
    started = time.perf_counter()
    try:
        experiment = dsage_ray.ablate(overrides=overrides, preset=args.preset, grid=args.grid, seeds=seeds,
                                      variants=variants, out=args.storage, workers=args.workers,
                                      address=args.address, resume=args.resume, api=args.api,
                                      max_failures=args.max_failures)
    except Interrupted as exc:
        print(f"interrupted: {exc}")
        return 130
    except DsageError as exc:
        print(f"ablation: error: {exc}", file=sys.stderr)
        return 2

    # 3. Where everything is.
    from dsage_ray.core.tensorboard_log import tensorboard_hint

    print(f"done in {time.perf_counter() - started:.0f}s: {experiment.path} ({len(experiment.trials)} trials)")
    print(f"table: python experiments/summarize.py {experiment.path}")
    print(f"open it in TensorBoard: {tensorboard_hint(experiment.path)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
