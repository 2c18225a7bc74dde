"""A finished ablation experiment → the paper's tables (Markdown) and a comparison plot (PNG).

    python experiments/summarize.py tb_logs/ablation_maze_cpu [--target 1107] [--out DIR]

Reads every trial folder Tune wrote (``params.json`` for the run's config, ``result.json`` with one
record per outer iteration). Per variant, as mean ± standard error over seeds:

- final QD-score and coverage (the paper's Table 1);
- evaluations needed to reach a fixed QD-score (its Table 2). The target is ``--target``, by
  default as the paper sets it: the mean final QD-score of MAP-Elites (Maze) or of DSAGE Basic
  (Mario). A run that never reaches it counts as its full budget, and the cell then reads
  "≥ …": the true figure is at least that.

Writes ``summary.md`` and ``comparison.png`` (QD-score and coverage against evaluations, a mean
line and a ± s.e. band per variant) into the experiment folder (or ``--out``).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from collections import defaultdict
from pathlib import Path

import numpy as np

from dsage_ray.config import ConfigError, RunConfig
from dsage_ray.core.metrics import evals_to_reach

#: The variant whose mean final QD-score is the paper's Table 2 target, per domain.
TARGET_VARIANT = {"maze": "map_elites", "mario": "dsage_basic"}


def load_trials(experiment: Path) -> list[dict]:
    """One record per trial: domain, variant, seed, budget and the per-iteration ``evals``/``qd_score``/``coverage``."""
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
            "domain": params.get("domain", "maze"),
            "variant": params.get("variant", "?"),
            "seed": params.get("seed", 0),
            "budget": _budget(params, rows),
            "done": bool(rows[-1].get("done")),
            "evals": np.array([r["evals"] for r in rows], dtype=float),
            "qd_score": np.array([r["qd_score"] for r in rows], dtype=float),
            "coverage": np.array([r["coverage"] for r in rows], dtype=float),
        })
    return trials


def _budget(params: dict, rows: list[dict]) -> int:
    """The trial's evaluation budget from its config (Tune keeps only keys that differ from the defaults)."""
    try:
        return RunConfig.build(params).budget
    except ConfigError:
        # A config this version no longer reads: a finished run spent exactly its budget.
        return int(params.get("budget", rows[-1]["evals"]))


def by_variant(trials: list[dict]) -> dict[str, list[dict]]:
    groups: dict[str, list[dict]] = defaultdict(list)
    for trial in trials:
        groups[trial["variant"]].append(trial)
    return dict(groups)


def mean_se(values) -> tuple[float, float]:
    """Mean and standard error; the error is NaN for a single run (it is not zero, just unknown)."""
    values = np.asarray(values, dtype=float)
    se = values.std(ddof=1) / math.sqrt(len(values)) if len(values) > 1 else math.nan
    return float(values.mean()), float(se)


def fmt(mean: float, se: float, spec: str) -> str:
    return format(mean, spec) if math.isnan(se) else f"{format(mean, spec)} ± {format(se, spec)}"


def default_target(trials: list[dict]) -> tuple[float, str]:
    """The paper's Table 2 target and where it comes from.

    Raises:
        ValueError: The experiment mixes domains, or lacks the variant that sets the target.
    """
    domains = sorted({t["domain"] for t in trials})
    if len(domains) != 1:
        raise ValueError(f"trials of several domains ({', '.join(domains)}): pass --target")
    variant = TARGET_VARIANT[domains[0]]
    runs = by_variant(trials).get(variant)
    if not runs:
        raise ValueError(f"no {variant} runs to set the default target (the paper's, for {domains[0]}): pass --target")
    target = mean_se([t["qd_score"][-1] for t in runs])[0]
    return target, f"the mean final QD-score of {variant} over {len(runs)} runs"


def evals_to_target(trial: dict, target: float) -> tuple[int, bool]:
    """Evaluations the run needed to reach ``target``, or its budget if it never did; and whether it did."""
    history = ({"evals": e, "qd_score": q} for e, q in zip(trial["evals"], trial["qd_score"]))
    reached = evals_to_reach(history, target)
    return (reached, True) if reached is not None else (trial["budget"], False)


def to_target_cell(runs: list[dict], target: float) -> str:
    """``mean ± se`` of the evaluations to reach ``target``; "≥" when a run never did (it counts its budget)."""
    counts, reached = zip(*(evals_to_target(t, target) for t in runs))
    text = fmt(*mean_se(counts), ",.0f")
    if all(reached):
        return text
    return f"≥ {text}" + (f" ({sum(reached)}/{len(runs)} reached)" if any(reached) else "")


def table(trials: list[dict], target: float) -> str:
    lines = [
        f"| Variant | Runs | QD-score | Coverage (%) | Evaluations to QD-score {target:,.1f} |",
        "|---|---|---|---|---|",
    ]
    groups = by_variant(trials)
    order = sorted(groups, key=lambda v: -mean_se([t["qd_score"][-1] for t in groups[v]])[0])
    for variant in order:
        runs = groups[variant]
        qd = mean_se([t["qd_score"][-1] for t in runs])
        cov = mean_se([100 * t["coverage"][-1] for t in runs])
        unfinished = sum(not t["done"] for t in runs)
        label = f"{len(runs)}" + (f" ({unfinished} unfinished)" if unfinished else "")
        lines.append(f"| {variant} | {label} | {fmt(*qd, ',.1f')} | {fmt(*cov, '.2f')} | "
                     f"{to_target_cell(runs, target)} |")
    return "\n".join(lines)


def mean_curve(runs: list[dict], key: str, grid: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Mean and standard error over runs of ``key`` at each point of an evaluation ``grid``.

    Each run's value at ``e`` evaluations is its value after the last outer iteration ending at or
    before ``e`` (0 before its first): seeds finish iterations at different evaluation counts. The
    error is 0 for a single run.
    """
    curves = np.stack([
        np.where(grid >= t["evals"][0], t[key][np.clip(np.searchsorted(t["evals"], grid, side="right") - 1, 0, None)], 0.0)
        for t in runs
    ])
    mean = curves.mean(axis=0)
    se = curves.std(axis=0, ddof=1) / math.sqrt(len(runs)) if len(runs) > 1 else np.zeros_like(mean)
    return mean, se


def plot(trials: list[dict], path: Path, *, target: float | None = None) -> None:
    """QD-score and coverage against evaluations: mean over seeds with a ± s.e. band, the target dashed."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(11, 4), dpi=100)
    for variant, runs in sorted(by_variant(trials).items()):
        grid = np.linspace(0, max(t["evals"][-1] for t in runs), 200)
        for ax, key, scale in ((axes[0], "qd_score", 1.0), (axes[1], "coverage", 100.0)):
            mean, se = mean_curve(runs, key, grid)
            (line,) = ax.plot(grid, scale * mean, label=f"{variant} ({len(runs)})")
            ax.fill_between(grid, scale * (mean - se), scale * (mean + se), color=line.get_color(), alpha=0.2)
    if target is not None:
        axes[0].axhline(target, color="grey", linestyle="--", linewidth=1, label=f"target {target:,.1f}")
    axes[0].set_ylabel("QD-score")
    axes[1].set_ylabel("coverage (%)")
    for ax in axes:
        ax.set_xlabel("evaluations")
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize="small")
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("experiment", type=Path, help="the experiment folder (storage/name)")
    parser.add_argument("--target", type=float,
                        help="QD-score for the evaluations-to-reach column (default: the paper's, see above)")
    parser.add_argument("--out", type=Path, help="where summary.md and comparison.png go (default: experiment)")
    args = parser.parse_args(argv)

    trials = load_trials(args.experiment)
    if not trials:
        print(f"summarize: no Tune trials with results under {args.experiment}", file=sys.stderr)
        return 1
    if args.target is not None:
        target, source = args.target, "--target"
    else:
        try:
            target, source = default_target(trials)
        except ValueError as exc:
            print(f"summarize: {exc}", file=sys.stderr)
            return 2
    markdown = (f"{table(trials, target)}\n\nEvaluations to QD-score {target:,.1f} ({source}); a run that never "
                f"reaches it counts as its budget (≥). Mean ± standard error over seeds.")
    print(markdown)
    out = args.out or args.experiment
    out.mkdir(parents=True, exist_ok=True)
    (out / "summary.md").write_text(markdown + "\n")
    plot(trials, out / "comparison.png", target=target)
    print(f"\nwrote {out / 'summary.md'} and {out / 'comparison.png'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
