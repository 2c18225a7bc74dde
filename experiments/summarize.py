"""A finished ablation experiment → the paper's tables (Markdown) and a comparison plot (PNG).

    python experiments/summarize.py tb_logs/ablation_maze_cpu [--target 1107] [--out DIR]
    python experiments/summarize.py NEW_EXPERIMENT OLD_EXPERIMENT:map_elites,dr --out DIR   # rows from two

An experiment may be followed by ``:VARIANT,VARIANT`` to take only those variants' trials from it, so
a table can combine variants re-run after a change with unchanged ones from an earlier experiment; a
variant found in two of the experiments given is an error (its runs would be mixed silently).

Reads the experiment through Tune's results API (:class:`ray.tune.ExperimentAnalysis`, offline: no
cluster needed): each trial's config, its grid values and its results, one per outer iteration.
Trials are grouped by variant and by every other grid key (``--grid surrogate.epochs=10,50`` gives
a row per variant and epoch count); seeds are what a group averages over. Per group, as mean ±
standard error over seeds:

- final QD-score and coverage (the paper's Table 1);
- evaluations needed to reach a fixed QD-score (its Table 2). The target is ``--target``, by
  default as the paper sets it: the mean final QD-score of MAP-Elites (Maze) or of DSAGE Basic
  (Mario). A run that never reaches it counts as its full budget, and the cell then reads
  "≥ …": the true figure is at least that.

Writes ``summary.md`` and ``comparison.png`` (QD-score and coverage against evaluations, a mean
line and a ± s.e. band per group) into the experiment folder (or ``--out``).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from collections import defaultdict
from pathlib import Path

import numpy as np
from ray import tune

from dsage_ray.config import ConfigError, RunConfig
from dsage_ray.core.metrics import evals_to_reach, format_mean_se, mean_se

#: The variant whose mean final QD-score is the paper's Table 2 target, per domain (other domains: --target).
TARGET_VARIANT = {"maze": "map_elites", "mario": "dsage_basic"}


#: Grid keys a group averages over rather than shows.
AVERAGED_KEYS = ("seed",)


def load_trials(experiment: Path) -> list[dict]:
    """One record per trial with results: domain, variant, seed, its other grid values, budget, whether
    it spent its budget, and the per-iteration ``evals``/``qd_score``/``coverage``.

    Raises:
        FileNotFoundError: ``experiment`` holds no Tune experiment.
    """
    try:
        # Tune (pyarrow) reads a relative path as a URI without a scheme and fails.
        analysis = tune.ExperimentAnalysis(str(Path(experiment).resolve()))
    except ValueError:  # Tune's message spans lines and names its internal file pattern
        raise FileNotFoundError(f"no Tune experiment under {experiment}") from None
    trials = []
    for trial in sorted(analysis.trials, key=lambda t: t.trial_id):
        rows = analysis.trial_dataframes.get(trial.trial_id)
        if rows is None or "qd_score" not in rows:
            continue
        # A trial restored after a crash reports again the iterations since its checkpoint: keep the last.
        rows = rows.dropna(subset=["qd_score"]).drop_duplicates("training_iteration", keep="last")
        rows = rows.sort_values("training_iteration")
        if rows.empty:
            continue
        config = trial.config
        evals = rows["evals"].to_numpy(dtype=float)
        budget = _budget(config, evals)
        trials.append({
            "domain": config.get("domain", "maze"),
            "variant": config.get("variant", "?"),
            "seed": config.get("seed", 0),
            "grid": {key: value for key, value in (trial.evaluated_params or {}).items()
                     if key != "variant" and key not in AVERAGED_KEYS},
            "budget": budget,
            "done": bool(evals[-1] >= budget),
            "evals": evals,
            "qd_score": rows["qd_score"].to_numpy(dtype=float),
            "coverage": rows["coverage"].to_numpy(dtype=float),
        })
    return trials


def split_spec(spec: str) -> tuple[Path, list[str] | None]:
    """``"folder:a,b"`` → ``(Path("folder"), ["a", "b"])``; a bare (or existing, colon-named) folder → ``(folder, None)``."""
    if Path(spec).exists() or ":" not in spec:
        return Path(spec), None
    folder, variants = spec.rsplit(":", 1)
    return Path(folder), [v.strip() for v in variants.split(",") if v.strip()]


def load_experiments(specs: list[str]) -> list[dict]:
    """The trials of several ``EXPERIMENT[:VARIANT,...]`` specs (:func:`load_trials`), filtered by variant.

    Raises:
        FileNotFoundError: A folder holds no Tune experiment.
        ValueError: A variant named after ``:`` has no trial there, or one variant has trials in two experiments.
    """
    trials, source = [], {}
    for spec in specs:
        folder, wanted = split_spec(spec)
        found = load_trials(folder)
        if wanted is not None:
            missing = sorted(set(wanted) - {t["variant"] for t in found})
            if missing:
                raise ValueError(f"{folder} has no trials of {', '.join(missing)}")
            found = [t for t in found if t["variant"] in wanted]
        for variant in sorted({t["variant"] for t in found}):
            if variant in source:
                raise ValueError(f"variant {variant} has trials in both {source[variant]} and {folder}: "
                                 f"choose one with EXPERIMENT:VARIANTS")
            source[variant] = folder
        trials += found
    return trials


def _budget(config: dict, evals: np.ndarray) -> int:
    """The trial's evaluation budget from its config (Tune keeps only keys that differ from the defaults)."""
    try:
        return RunConfig.build(config).budget
    except ConfigError:
        # A config this version no longer reads: a finished run spent exactly its budget.
        return int(config.get("budget", evals[-1]))


def grid_keys(trials: list[dict]) -> list[str]:
    """The grid keys besides variant and seed, in the order the grid gave them."""
    return list(dict.fromkeys(key for trial in trials for key in trial["grid"]))


def group_label(trial: dict, keys: list[str]) -> tuple[str, ...]:
    """The variant, then the trial's value of each grid key (``-`` where it has none)."""
    return (trial["variant"], *(_show(trial["grid"][key]) if key in trial["grid"] else "-" for key in keys))


def _show(value) -> str:
    return value if isinstance(value, str) else json.dumps(value)


def by_group(trials: list[dict]) -> dict[tuple[str, ...], list[dict]]:
    """Trials grouped by variant and every other grid key."""
    keys = grid_keys(trials)
    groups: dict[tuple[str, ...], list[dict]] = defaultdict(list)
    for trial in trials:
        groups[group_label(trial, keys)].append(trial)
    return dict(groups)


def by_variant(trials: list[dict]) -> dict[str, list[dict]]:
    groups: dict[str, list[dict]] = defaultdict(list)
    for trial in trials:
        groups[trial["variant"]].append(trial)
    return dict(groups)


def default_target(trials: list[dict]) -> tuple[float, str]:
    """The paper's Table 2 target and where it comes from.

    Raises:
        ValueError: The experiment mixes domains, or lacks the variant that sets the target.
    """
    domains = sorted({t["domain"] for t in trials})
    if len(domains) != 1:
        raise ValueError(f"trials of several domains ({', '.join(domains)}): pass --target")
    variant = TARGET_VARIANT.get(domains[0])
    if variant is None:
        raise ValueError(f"the paper sets no target for domain {domains[0]!r}: pass --target")
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
    text = format_mean_se(*mean_se(counts), ",.0f")
    if all(reached):
        return text
    return f"≥ {text}" + (f" ({sum(reached)}/{len(runs)} reached)" if any(reached) else "")


def table(trials: list[dict], target: float) -> str:
    keys = grid_keys(trials)
    lines = [
        "| " + " | ".join(["Variant", *keys]) + f" | Runs | QD-score | Coverage (%) | Evaluations to QD-score {target:,.1f} |",
        "|" + "---|" * (len(keys) + 5),
    ]
    groups = by_group(trials)
    order = sorted(groups, key=lambda label: -mean_se([t["qd_score"][-1] for t in groups[label]])[0])
    for label in order:
        runs = groups[label]
        qd = mean_se([t["qd_score"][-1] for t in runs])
        cov = mean_se([100 * t["coverage"][-1] for t in runs])
        unfinished = sum(not t["done"] for t in runs)
        count = f"{len(runs)}" + (f" ({unfinished} unfinished)" if unfinished else "")
        lines.append(f"| {' | '.join(label)} | {count} | {format_mean_se(*qd, ',.1f')} | {format_mean_se(*cov, '.2f')} | "
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
    keys = grid_keys(trials)
    for label, runs in sorted(by_group(trials).items()):
        name = " ".join([label[0], *(f"{key}={value}" for key, value in zip(keys, label[1:]))])
        grid = np.linspace(0, max(t["evals"][-1] for t in runs), 200)
        for ax, key, scale in ((axes[0], "qd_score", 1.0), (axes[1], "coverage", 100.0)):
            mean, se = mean_curve(runs, key, grid)
            (line,) = ax.plot(grid, scale * mean, label=f"{name} ({len(runs)})")
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
    parser.add_argument("experiments", nargs="+", metavar="EXPERIMENT[:VARIANTS]",
                        help="experiment folder(s) (storage/name), each optionally with :v1,v2 to take only those variants")
    parser.add_argument("--target", type=float,
                        help="QD-score for the evaluations-to-reach column (default: the paper's, see above)")
    parser.add_argument("--out", type=Path, help="where summary.md and comparison.png go (default: experiment)")
    args = parser.parse_args(argv)

    try:
        trials = load_experiments(args.experiments)
    except (FileNotFoundError, ValueError) as exc:
        print(f"summarize: {exc}", file=sys.stderr)
        return 1
    if not trials:
        print(f"summarize: no Tune trials with results under {', '.join(args.experiments)}", file=sys.stderr)
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
    out = args.out or split_spec(args.experiments[0])[0]
    out.mkdir(parents=True, exist_ok=True)
    (out / "summary.md").write_text(markdown + "\n")
    plot(trials, out / "comparison.png", target=target)
    print(f"\nwrote {out / 'summary.md'} and {out / 'comparison.png'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
