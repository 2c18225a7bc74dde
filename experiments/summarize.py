"""A finished ablation experiment → the paper's table (Markdown) and a comparison plot (PNG).

    python experiments/summarize.py tb_logs/ablation_maze_tiny [--target 10] [--out DIR]

Reads every trial folder Tune wrote (``params.json`` for variant and seed, ``result.json`` with one
record per outer iteration). Per variant: final QD-score and coverage as mean ± standard error over
seeds, and the evaluations needed to reach a QD-score of ``--target`` (the paper's Table 2 metric;
default: half the best final QD-score of the experiment) over the seeds that reached it.
Writes ``summary.md`` and ``comparison.png`` into the experiment folder (or ``--out``).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from collections import defaultdict
from pathlib import Path

import numpy as np

from dsage_ray.core.metrics import evals_to_reach


def load_trials(experiment: Path) -> list[dict]:
    """One record per trial: variant, seed and the per-iteration ``evals``/``qd_score``/``coverage``."""
    trials = []
    for params_file in sorted(experiment.glob("*/params.json")):
        params = json.loads(params_file.read_text())
        results_file = params_file.with_name("result.json")
        rows = [json.loads(line) for line in results_file.read_text().splitlines() if line.strip()] \
            if results_file.exists() else []
        # A trial restored after a crash repeats the iterations since its checkpoint: keep the last.
        by_iteration = {row["training_iteration"]: row for row in rows if "qd_score" in row}
        rows = [by_iteration[i] for i in sorted(by_iteration)]
        if not rows:
            continue
        trials.append({
            "variant": params.get("variant", "?"),
            "seed": params.get("seed", 0),
            "done": bool(rows[-1].get("done")),
            "evals": np.array([r["evals"] for r in rows], dtype=float),
            "qd_score": np.array([r["qd_score"] for r in rows], dtype=float),
            "coverage": np.array([r["coverage"] for r in rows], dtype=float),
        })
    return trials


def mean_se(values: list[float]) -> tuple[float, float]:
    """Mean and standard error; the error is NaN for a single run (it is not zero, just unknown)."""
    values = np.asarray(values, dtype=float)
    se = values.std(ddof=1) / math.sqrt(len(values)) if len(values) > 1 else math.nan
    return float(values.mean()), float(se)


def fmt(mean: float, se: float, spec: str) -> str:
    return format(mean, spec) if math.isnan(se) else f"{format(mean, spec)} ± {format(se, spec)}"


def trial_evals_to_reach(trial: dict, target: float) -> int | None:
    history = ({"evals": e, "qd_score": q} for e, q in zip(trial["evals"], trial["qd_score"]))
    return evals_to_reach(history, target)


def table(trials: list[dict], target: float) -> str:
    by_variant: dict[str, list[dict]] = defaultdict(list)
    for trial in trials:
        by_variant[trial["variant"]].append(trial)
    lines = [
        f"| Variant | Runs | QD-score | Coverage (%) | Evaluations to QD-score {target:g} |",
        "|---|---|---|---|---|",
    ]
    order = sorted(by_variant, key=lambda v: -mean_se([t["qd_score"][-1] for t in by_variant[v]])[0])
    for variant in order:
        runs = by_variant[variant]
        qd = mean_se([t["qd_score"][-1] for t in runs])
        cov = mean_se([100 * t["coverage"][-1] for t in runs])
        reached = [e for e in (trial_evals_to_reach(t, target) for t in runs) if e is not None]
        if reached:
            to_target = fmt(*mean_se(reached), ",.0f") + ("" if len(reached) == len(runs) else f" ({len(reached)}/{len(runs)} runs)")
        else:
            to_target = f"not reached (0/{len(runs)})"
        unfinished = sum(not t["done"] for t in runs)
        label = f"{len(runs)}" + (f" ({unfinished} unfinished)" if unfinished else "")
        lines.append(f"| {variant} | {label} | {fmt(*qd, '.1f')} | {fmt(*cov, '.2f')} | {to_target} |")
    return "\n".join(lines)


def plot(trials: list[dict], path: Path) -> None:
    """QD-score and coverage against evaluations: mean over seeds with a ± s.e. band."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    by_variant: dict[str, list[dict]] = defaultdict(list)
    for trial in trials:
        by_variant[trial["variant"]].append(trial)
    fig, axes = plt.subplots(1, 2, figsize=(11, 4), dpi=100)
    for variant, runs in sorted(by_variant.items()):
        # Seeds evaluate in different batch sizes: compare on a common evaluation grid (step-wise).
        grid = np.linspace(0, max(t["evals"][-1] for t in runs), 200)
        for ax, key, scale in ((axes[0], "qd_score", 1.0), (axes[1], "coverage", 100.0)):
            curves = np.stack([scale * t[key][np.clip(np.searchsorted(t["evals"], grid, side="right") - 1, 0, None)]
                               * (grid >= t["evals"][0]) for t in runs])
            mean = curves.mean(axis=0)
            se = curves.std(axis=0, ddof=1) / math.sqrt(len(runs)) if len(runs) > 1 else np.zeros_like(mean)
            (line,) = ax.plot(grid, mean, label=variant)
            ax.fill_between(grid, mean - se, mean + se, color=line.get_color(), alpha=0.2)
    axes[0].set_ylabel("QD-score")
    axes[1].set_ylabel("coverage (%)")
    for ax in axes:
        ax.set_xlabel("evaluations")
        ax.grid(alpha=0.3)
    axes[0].legend()
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("experiment", type=Path, help="the experiment folder (storage/name)")
    parser.add_argument("--target", type=float, help="QD-score for the evaluations-to-reach column")
    parser.add_argument("--out", type=Path, help="where summary.md and comparison.png go (default: experiment)")
    args = parser.parse_args()

    trials = load_trials(args.experiment)
    if not trials:
        print(f"no Tune trials with results under {args.experiment}", file=sys.stderr)
        return 1
    target = args.target if args.target is not None else 0.5 * max(t["qd_score"][-1] for t in trials)
    markdown = table(trials, target)
    print(markdown)
    out = args.out or args.experiment
    out.mkdir(parents=True, exist_ok=True)
    (out / "summary.md").write_text(markdown + "\n")
    plot(trials, out / "comparison.png")
    print(f"\nwrote {out / 'summary.md'} and {out / 'comparison.png'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
