"""How often the nominal check's "far worse" rule would stop a good agent, measured on RL Zoo training records.

The audit's nominal check (:mod:`dsage_ray.audit.nominal`) stops where an agent's mean return over ``n`` nominal
episodes falls below ``E − max(0.25·|E|, 3·s·√(2/n))``, ``E`` the expected return (a zoo folder's last
``evaluations.npz`` row), ``s`` the episodes' standard deviation. This script draws ``n``-episode checks from each
folder's own recorded episodes (its last row, and its last ten rows pooled: the policy's drift at the end of
training) and prints how often each rule stops them: the relative margin alone, and the rule::

    python benchmarks/nominal_rule.py ../shared/models/rl_zoo --episodes 10 --draws 20000

Read-only: ``evaluations.npz`` is loaded without pickles.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from dsage_ray.audit.nominal import RELATIVE_MARGIN, far_worse_threshold


def false_stops(expected: float, episodes_pool: np.ndarray, *, episodes: int, draws: int,
                rng: np.random.Generator) -> tuple[float, float]:
    """The share of ``draws`` checks of ``episodes`` episodes (drawn from ``episodes_pool``) stopped by the relative
    margin alone and by the rule."""
    samples = rng.choice(np.asarray(episodes_pool, dtype=np.float64), size=(draws, episodes))
    means, stds = samples.mean(axis=1), samples.std(axis=1, ddof=1)
    relative = float(np.mean(means < expected - RELATIVE_MARGIN * abs(expected)))
    thresholds = np.array([far_worse_threshold(expected, return_std=s, episodes=episodes) for s in stds])
    return relative, float(np.mean(means < thresholds))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("root", type=Path, help="a folder of zoo run folders (ALGO/ENV_1/evaluations.npz)")
    parser.add_argument("--episodes", type=int, default=10, help="episodes per nominal check (the gym domain's 10)")
    parser.add_argument("--draws", type=int, default=20_000)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    rng = np.random.default_rng(args.seed)
    print(f"{'folder':28s} {'E':>8s} {'episodes drawn from':20s} {'0.25|E| alone':>14s} {'the rule':>9s}")
    for path in sorted(args.root.glob("*/*/evaluations.npz")):
        with np.load(path, allow_pickle=False) as data:
            results = np.asarray(data["results"], dtype=np.float64)
        expected = float(results[-1].mean())
        name = str(path.parent.relative_to(args.root))
        for label, pool in (("its last row", results[-1]), ("its last 10 rows", results[-10:].ravel())):
            relative, rule = false_stops(expected, pool, episodes=args.episodes, draws=args.draws, rng=rng)
            print(f"{name:28s} {expected:8.1f} {label:20s} {relative:14.4f} {rule:9.4f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
