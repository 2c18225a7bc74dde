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
  "≥ …": the true figure is at least that. Without a target (no ``--target`` and no run of the
  variant that sets it, e.g. a grid of DSAGE alone) the table has no such column and says why.

Then the same groups at *equal wall time*: QD-score, coverage and evaluations at the smallest final
wall time of all the runs (the rows' cumulative ``wall_time``: time spent stepping, resumes
included), each run read as a step function (an outer iteration's values exist once it ends).
Experiments written before rows carried ``wall_time`` get a one-line note instead. Wall time depends
on the machine and its load: compare only runs that shared the same kind of machine.

Writes ``summary.md`` and ``comparison.png`` (QD-score and coverage against evaluations and, when the
rows carry it, against wall time: a mean line and a ± s.e. band per group) into the experiment folder
(or ``--out``).
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

# The result tables' figures are research code shared with the benchmarks, kept beside them.
BENCHMARKS = Path(__file__).resolve().parents[1] / "benchmarks"
if str(BENCHMARKS) not in sys.path:
    sys.path.insert(0, str(BENCHMARKS))
from metrics import evals_to_reach, format_mean_se, mean_se  # noqa: E402

#: The variant whose mean final QD-score is the paper's Table 2 target, per domain (other domains: --target).
TARGET_VARIANT = {"maze": "map_elites", "mario": "dsage_basic"}


#: Grid keys a group averages over rather than shows.
AVERAGED_KEYS = ("seed",)


def load_trials(experiment: Path) -> list[dict]:
    """One record per trial with results: domain, variant, seed, its other grid values, budget, whether
    it spent its evaluation or time budget, and the per-iteration ``evals``/``qd_score``/``coverage`` and
    ``wall_time`` (``None`` for rows written before it was recorded).

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
        budget, time_budget = _budgets(config, evals)
        wall_time = rows["wall_time"].to_numpy(dtype=float) if "wall_time" in rows else None
        if wall_time is not None and np.isnan(wall_time).any():
            wall_time = None  # rows of a run resumed by a newer version after an older one: no common clock
        trials.append({
            "domain": config.get("domain", "maze"),
            "variant": config.get("variant", "?"),
            "seed": config.get("seed", 0),
            "grid": {key: value for key, value in (trial.evaluated_params or {}).items()
                     if key != "variant" and key not in AVERAGED_KEYS},
            "budget": budget,
            "done": bool(evals[-1] >= budget or (wall_time is not None and 0 < time_budget <= wall_time[-1])),
            "evals": evals,
            "qd_score": rows["qd_score"].to_numpy(dtype=float),
            "coverage": rows["coverage"].to_numpy(dtype=float),
            "wall_time": wall_time,
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


def _budgets(config: dict, evals: np.ndarray) -> tuple[int, float]:
    """The trial's evaluation and time budgets from its config (Tune keeps only keys that differ from the
    defaults); a time budget of 0 is none."""
    try:
        built = RunConfig.build(config)
        return built.budget, built.time_budget
    except ConfigError:
        # A config this version no longer reads: a finished run spent exactly its budget.
        return int(config.get("budget", evals[-1])), float(config.get("time_budget", 0.0))


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


def table(trials: list[dict], target: float | None) -> str:
    """The equal-evaluation table: final QD-score and coverage per group and, given a ``target``, the
    evaluations each group needed to reach it."""
    keys = grid_keys(trials)
    to_target = [f"Evaluations to QD-score {target:,.1f}"] if target is not None else []
    lines = [_header(keys, ["Runs", "QD-score", "Coverage (%)", *to_target])]
    groups = by_group(trials)
    order = sorted(groups, key=lambda label: -mean_se([t["qd_score"][-1] for t in groups[label]])[0])
    for label in order:
        runs = groups[label]
        qd = mean_se([t["qd_score"][-1] for t in runs])
        cov = mean_se([100 * t["coverage"][-1] for t in runs])
        unfinished = sum(not t["done"] for t in runs)
        count = f"{len(runs)}" + (f" ({unfinished} unfinished)" if unfinished else "")
        cells = [count, format_mean_se(*qd, ',.1f'), format_mean_se(*cov, '.2f')]
        if target is not None:
            cells.append(to_target_cell(runs, target))
        lines.append(_row(label, cells))
    return "\n".join(lines)


def common_wall_time(trials: list[dict]) -> float | None:
    """The equal-time comparison's time: the smallest final ``wall_time`` of all runs (every run got that
    far), or ``None`` when some run's rows carry no wall time."""
    if any(t["wall_time"] is None for t in trials):
        return None
    return min(float(t["wall_time"][-1]) for t in trials)


def time_table(trials: list[dict], seconds: float) -> str:
    """The equal-time table: per group, QD-score, coverage and evaluations at ``seconds`` of wall time
    (:func:`values_at`), and the runs' full wall time, as mean ± s.e. over seeds."""
    keys = grid_keys(trials)
    lines = [_header(keys, ["Runs", f"QD-score at {seconds:,.0f} s", "Coverage (%)", "Evaluations",
                            "Full run (s)"])]
    groups = by_group(trials)
    at = np.array([seconds])

    def cell(runs: list[dict], key: str, spec: str, scale: float = 1.0) -> str:
        return format_mean_se(*mean_se(scale * values_at(runs, key, at, x="wall_time")[:, 0]), spec)

    order = sorted(groups, key=lambda label: -mean_se(values_at(groups[label], "qd_score", at, x="wall_time")[:, 0])[0])
    for label in order:
        runs = groups[label]
        lines.append(_row(label, [str(len(runs)), cell(runs, "qd_score", ",.1f"), cell(runs, "coverage", ".2f", 100.0),
                                  cell(runs, "evals", ",.0f"),
                                  format_mean_se(*mean_se(t["wall_time"][-1] for t in runs), ",.0f")]))
    return "\n".join(lines)


def _header(keys: list[str], columns: list[str]) -> str:
    return "| " + " | ".join(["Variant", *keys, *columns]) + " |\n|" + "---|" * (1 + len(keys) + len(columns))


def _row(label: tuple[str, ...], cells: list[str]) -> str:
    return f"| {' | '.join(label)} | {' | '.join(cells)} |"


def values_at(runs: list[dict], key: str, grid: np.ndarray, *, x: str = "evals") -> np.ndarray:
    """``(runs, points)``: each run's ``key`` at each point of ``grid`` on the axis ``x`` (``evals`` or
    ``wall_time``), read as a step function: the value after the last outer iteration ending at or
    before the point, 0 before its first (its values exist only once an iteration ends)."""
    return np.stack([
        np.where(grid >= t[x][0], t[key][np.clip(np.searchsorted(t[x], grid, side="right") - 1, 0, None)], 0.0)
        for t in runs
    ])


def mean_curve(runs: list[dict], key: str, grid: np.ndarray, *, x: str = "evals") -> tuple[np.ndarray, np.ndarray]:
    """Mean and standard error over runs of ``key`` at each point of a ``grid`` of evaluations (or of
    wall time, with ``x="wall_time"``).

    Each run's value at ``e`` evaluations is its value after the last outer iteration ending at or
    before ``e`` (0 before its first): seeds finish iterations at different evaluation counts. The
    error is 0 for a single run.
    """
    curves = values_at(runs, key, grid, x=x)
    mean = curves.mean(axis=0)
    se = curves.std(axis=0, ddof=1) / math.sqrt(len(runs)) if len(runs) > 1 else np.zeros_like(mean)
    return mean, se


def plot(trials: list[dict], path: Path, *, target: float | None = None, at_time: float | None = None) -> None:
    """QD-score and coverage against evaluations (top) and, given ``at_time`` (the equal-time table's
    time, dotted), against wall time (bottom): mean over seeds with a ± s.e. band, the target dashed."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    axes_x = ["evals"] + (["wall_time"] if at_time is not None else [])
    fig, axes = plt.subplots(len(axes_x), 2, figsize=(11, 4 * len(axes_x)), dpi=100, squeeze=False)
    keys = grid_keys(trials)
    for label, runs in sorted(by_group(trials).items()):
        name = " ".join([label[0], *(f"{key}={value}" for key, value in zip(keys, label[1:]))])
        for row, x in zip(axes, axes_x):
            grid = np.linspace(0, max(t[x][-1] for t in runs), 200)
            for ax, key, scale in ((row[0], "qd_score", 1.0), (row[1], "coverage", 100.0)):
                mean, se = mean_curve(runs, key, grid, x=x)
                (line,) = ax.plot(grid, scale * mean, label=f"{name} ({len(runs)})")
                ax.fill_between(grid, scale * (mean - se), scale * (mean + se), color=line.get_color(), alpha=0.2)
    for row, x in zip(axes, axes_x):
        if target is not None:
            row[0].axhline(target, color="grey", linestyle="--", linewidth=1, label=f"target {target:,.1f}")
        row[0].set_ylabel("QD-score")
        row[1].set_ylabel("coverage (%)")
        for ax in row:
            ax.set_xlabel("evaluations" if x == "evals" else "wall time (s)")
            ax.grid(alpha=0.3)
        row[0].legend(fontsize="small")
    if at_time is not None:
        for ax in axes[1]:
            ax.axvline(at_time, color="grey", linestyle=":", linewidth=1)
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
    target: float | None
    if args.target is not None:
        target, source = args.target, "--target"
    else:
        try:
            target, source = default_target(trials)
        except ValueError as exc:
            # Still a table, without the column that needs a target: e.g. a grid of DSAGE alone.
            target, source = None, str(exc)
    if target is not None:
        note = (f"Evaluations to QD-score {target:,.1f} ({source}); a run that never reaches it counts as its "
                f"budget (≥). Mean ± standard error over seeds.")
    else:
        note = f"Mean ± standard error over seeds. No evaluations-to-target column: {source}."
    at_time = common_wall_time(trials)
    if at_time is not None:
        timed = (f"At equal wall time ({at_time:,.0f} s, the shortest run's; wall time is time spent stepping, "
                 f"on this experiment's machines):\n\n{time_table(trials, at_time)}")
    else:
        timed = "No equal-time table: some runs' rows carry no wall_time (written before it was recorded)."
    markdown = f"{table(trials, target)}\n\n{note}\n\n{timed}"
    print(markdown)
    out = args.out or split_spec(args.experiments[0])[0]
    out.mkdir(parents=True, exist_ok=True)
    (out / "summary.md").write_text(markdown + "\n")
    plot(trials, out / "comparison.png", target=target, at_time=at_time)
    print(f"\nwrote {out / 'summary.md'} and {out / 'comparison.png'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
