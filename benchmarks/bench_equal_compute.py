"""DSAGE against a baseline at equal evaluations AND at equal compute, with the cost curve that explains the gap.

Reads finished run folders (``dsage-ray run … --local --out DIR``: each holds ``config.json`` and
``metrics.json``, one row per outer iteration) and prints, per variant, as mean ± standard error over
seeds:

1. **Equal evaluations**: QD-score at ``--at-evals`` real evaluations (linear between the two outer
   iterations around it; a run that stopped short counts with its last value, marked).
2. **Equal time**: QD-score at ``--at-time`` seconds of the run's clock (default: the shortest run's
   final time), read as a step function: an outer iteration's QD-score exists only once it ends. Then,
   paired by seed, each run's final QD-score against the baseline's at the second that run ended: a
   common horizon can catch a run with long outer iterations almost a whole iteration before its
   next step, so the paired reading is the fairer one.
   ``--clock wall`` (default) or ``cpu`` uses the rows' cumulative ``wall_time`` / ``cpu_time``;
   rows written before those columns existed fall back to the summed ``time_total``.
3. **Cost profile** of each surrogate variant: the share of its time spent training, in the inner loop,
   selecting, evaluating and on the held-out diagnostic.
4. **Why**: the same comparison with the surrogate free (each run's clock counting only its
   evaluations), which bounds what any speed-up of the surrogate can buy; and the simulator cost at
   which the surrogate variant breaks even with the baseline at equal time (the evaluation cost scaled
   by k for both searches, the surrogate's own time fixed).
5. **The counting bound**: one evaluation fills at most one archive cell, so at the second a surrogate
   run ended it could at best stand at (its evaluations × QD-score per elite) / the baseline's QD-score
   then; and with the surrogate free, at as many evaluations as its evaluation seconds per level allow.
   It prints the share of evaluations that would have to fill a new cell to reach ``--target``.

    python benchmarks/bench_equal_compute.py /work/runs/eq/dsage_s1* /work/runs/eq/map_elites_s1* \\
        --baseline map_elites --at-evals 2000
"""

from __future__ import annotations

import argparse
import json
import sys
from collections import defaultdict
from pathlib import Path

import numpy as np
from metrics import format_mean_se, mean_se  # this script's folder is on sys.path when run

#: Phases a surrogate outer iteration is timed in (``time_<phase>`` metric columns).
PHASES = ("train", "exploit", "select", "evaluate", "holdout")


def mean_pm(values: list[float], spec: str = ",.1f") -> str:
    """``"1,597.0 ± 17.5"`` over runs."""
    return format_mean_se(*mean_se(values), spec)


def load_run(folder: Path) -> dict:
    """A run folder's variant, seed and per-iteration history (with a cumulative clock per row).

    Raises:
        SystemExit: ``folder`` is not a finished run folder.
    """
    # A --local run folder has config.json; a Tune trial folder has params.json (the flat config).
    config_file = folder / "config.json" if (folder / "config.json").exists() else folder / "params.json"
    try:
        config = json.loads(config_file.read_text())
        history = json.loads((folder / "metrics.json").read_text())
    except (OSError, ValueError) as exc:
        raise SystemExit(f"{folder}: not a finished run folder (config.json or params.json, and metrics.json): "
                         f"{exc}") from None
    if isinstance(history, dict):
        history = history.get("history", [])
    if not history:
        raise SystemExit(f"{folder}: metrics.json holds no outer iteration")
    summed = np.cumsum([row.get("time_total", 0.0) for row in history])
    for row, fallback in zip(history, summed):
        row.setdefault("wall_time", float(fallback))
        row.setdefault("cpu_time", float(fallback))
    domain = config.get("domain", "maze")
    screen_episodes = _config_value(config, "selection.screen_episodes", 0)
    episodes = _config_value(config, f"{domain}.episodes", 0)
    return {"folder": folder, "variant": config.get("variant", "?"), "name": config.get("name", "?"),
            "seed": config.get("seed", 0), "history": history,
            # What one screened level costs in evaluations (episodes), 0 without a screen.
            "screen_share": screen_episodes / episodes if screen_episodes and episodes else 0.0}


def _config_value(config: dict, key: str, default):
    """A key of a nested ``config.json`` or of a flat ``params.json``."""
    if key in config:
        return config[key]
    node = config
    for part in key.split("."):
        if not isinstance(node, dict) or part not in node:
            return default
        node = node[part]
    return node


def qd_at_evals(history: list[dict], evals: float) -> tuple[float, bool]:
    """QD-score at ``evals`` evaluations, linear between outer iterations; ``(value, reached)``."""
    xs = np.array([0.0] + [row["evals"] for row in history])
    ys = np.array([0.0] + [row["qd_score"] for row in history])
    if evals > xs[-1]:
        return float(ys[-1]), False
    return float(np.interp(evals, xs, ys)), True


def phase_seconds(history: list[dict], clock: str) -> list[dict[str, float]]:
    """Each outer iteration's seconds on ``clock``, split into its phases.

    The ``time_<phase>`` columns are wall seconds; each iteration's shares of them are applied to its
    seconds on ``clock``, so that on a shared machine the ``cpu`` clock stays the run's own compute.
    In a pipelined run the surrogate's phases ran while the batch was out (``time_overlapped``); its
    ``evaluate`` is then only the time the driver waited for the simulators beyond that.
    """
    rows, previous = [], 0.0
    for row in history:
        span, previous = row[f"{clock}_time"] - previous, row[f"{clock}_time"]
        total = row.get("time_total", 0.0)
        seconds = {phase: row.get(f"time_{phase}", 0.0) for phase in PHASES}
        seconds["evaluate"] = max(seconds["evaluate"] - row.get("time_overlapped", 0.0), 0.0)
        shares = {phase: value / total if total > 0 else 0.0 for phase, value in seconds.items()}
        rows.append({"total": span, **{phase: span * share for phase, share in shares.items()}})
    return rows


def evaluation_ends(history: list[dict], clock: str) -> np.ndarray:
    """Cumulative evaluation seconds on ``clock`` at each outer iteration's end (the run, surrogate free)."""
    return np.cumsum([row["evaluate"] for row in phase_seconds(history, clock)])


def qd_at_time(history: list[dict], seconds: float, clock: str, *, evaluation_only: bool = False,
               key: str = "qd_score") -> float:
    """QD-score (or another metric, ``key``) of the last outer iteration that ended by ``seconds`` on ``clock``
    (0 before the first).

    With ``evaluation_only`` the clock counts only the evaluations (:func:`evaluation_ends`): the run as
    it would be with a free surrogate.
    """
    if evaluation_only:
        ends = evaluation_ends(history, clock)
    else:
        ends = np.array([row[f"{clock}_time"] for row in history])
    done = [row.get(key, 0.0) for row, end in zip(history, ends) if end <= seconds]
    return float(done[-1]) if done else 0.0


def run_end(run: dict, clock: str, *, evaluation_only: bool = False) -> float:
    """When ``run``'s last outer iteration ended on ``clock`` (or after its evaluations alone)."""
    if evaluation_only:
        return float(evaluation_ends(run["history"], clock)[-1])
    return float(run["history"][-1][f"{clock}_time"])


def same_seed_pairs(group: list[dict], baseline: list[dict]) -> list[tuple[dict, dict]]:
    """``(run, the baseline run of its seed)`` for every run of ``group`` whose seed the baseline has."""
    baseline_by_seed = {run["seed"]: run for run in baseline}
    return [(run, baseline_by_seed[run["seed"]]) for run in group if run["seed"] in baseline_by_seed]


def paired_at_own_end(group: list[dict], baseline: list[dict], clock: str, *, evaluation_only: bool = False,
                      at_evals: float | None = None) -> list[tuple[int, float, float, bool]]:
    """Each run's final QD-score against the same seed's baseline run at the same second.

    A surrogate run's QD-score moves only when an outer iteration ends, and its few outer iterations are
    long, so a reading at a horizon set by another run catches it anywhere up to a whole iteration behind
    its next step. Reading each run where its own last iteration ended and the baseline (whose steps are one
    batch apart) at that second compares two exact step values.

    Args:
        at_evals: Read each run instead where the outer iteration that reached this many evaluations ended
            (the run as if its budget had stopped it there); runs that never reached it are left out.

    Returns:
        ``(seed, own QD-score, baseline QD-score then, baseline ran that long)`` for every seed both have.
    """
    pairs = []
    for run, other in same_seed_pairs(group, baseline):
        history = run["history"]
        last = len(history) - 1 if at_evals is None else next(
            (i for i, row in enumerate(history) if row["evals"] >= at_evals), None)
        if last is None:
            continue
        ends = evaluation_ends(history, clock) if evaluation_only else [row[f"{clock}_time"] for row in history]
        end = float(ends[last])
        pairs.append((run["seed"], float(history[last]["qd_score"]),
                      qd_at_time(other["history"], end, clock, evaluation_only=evaluation_only),
                      run_end(other, clock, evaluation_only=evaluation_only) >= end))
    return pairs


def print_by_length(variant: str, baseline: str, group: list[dict], baseline_runs: list[dict], clock: str,
                    lengths: list[float]) -> None:
    """The equal-evaluation and the paired equal-time ratios of runs stopped at each budget in ``lengths``."""
    print(f"\n{variant} / {baseline} by run length: each {variant} run read where its outer iteration that reached "
          f"the budget ended, the same seed's {baseline} run at the same evaluations and at the same {clock} second")
    print(f"| budget (evaluations) | seeds | {variant} QD-score | at equal evaluations | at equal {clock} time |")
    print("|---|---|---|---|---|")
    histories = {run["seed"]: run["history"] for run in group}
    base_histories = {run["seed"]: run["history"] for run in baseline_runs}
    for length in lengths:
        pairs = paired_at_own_end(group, baseline_runs, clock, at_evals=length)
        if not pairs:
            print(f"| {length:,.0f} | 0 | no {variant} run reached it | | |")
            continue
        base_at_length = [qd_at_evals(base_histories[seed], length) for seed, *_ in pairs]
        per_eval = [qd_at_evals(histories[seed], length)[0] / max(base, 1e-9)
                    for (seed, *_), (base, _) in zip(pairs, base_at_length)]
        at_time = [own / max(base, 1e-9) for _, own, base, _ in pairs]
        fewer = sum(not reached for _, reached in base_at_length)
        short = sum(not long_enough for *_, long_enough in pairs)
        evals_note = f" ({fewer} {baseline} run(s) made fewer evaluations)" if fewer else ""
        time_note = f" ({short} {baseline} run(s) stopped before that second)" if short else ""
        print(f"| {length:,.0f} | {len(pairs)} | {mean_pm([own for _, own, _, _ in pairs])} | "
              f"{mean_pm(per_eval, '.2f')}x{evals_note} | {mean_pm(at_time, '.2f')}x{time_note} |")


def time_to_reach(history: list[dict], qd_score: float, clock: str) -> float | None:
    """The ``clock`` second at which the outer iteration that first reached ``qd_score`` ended, or ``None``."""
    return next((float(row[f"{clock}_time"]) for row in history if row["qd_score"] >= qd_score), None)


def print_time_to_reach(variant: str, group: list[dict], baseline: list[dict], clock: str) -> None:
    """Per seed: how long the baseline took to reach the run's final QD-score, against the run's own time."""
    speedups = []
    for run, other in same_seed_pairs(group, baseline):
        target, own = run["history"][-1]["qd_score"], run_end(run, clock)
        reached = time_to_reach(other["history"], target, clock)
        if reached is None:
            print(f"  seed {run['seed']}: {variant} reached {target:,.1f} at {own:,.0f} s; the baseline never did "
                  f"(in {run_end(other, clock):,.0f} s)")
            continue
        speedups.append(reached / max(own, 1e-9))
        print(f"  seed {run['seed']}: {variant} reached {target:,.1f} at {own:,.0f} s, the baseline at "
              f"{reached:,.0f} s → {speedups[-1]:.2f}x")
    if speedups:
        print(f"baseline's time / {variant}'s time to {variant}'s final QD-score ({clock}): "
              f"{mean_pm(speedups, '.2f')}x over {len(speedups)} seeds")


def selected_batch_errors(run: dict, *, first_iteration: int = 3) -> dict[str, float]:
    """Per measure, the median over outer iterations ``first_iteration``+ of the surrogate's MAE on the levels
    it picked (the rows' ``mae_<measure>``, measured when the batch was evaluated); empty without any."""
    errors: dict[str, list[float]] = defaultdict(list)
    for row in run["history"]:
        if row.get("outer_iteration", 0) < first_iteration:
            continue
        for key, value in row.items():
            if key.startswith("mae_") and key not in ("mae_objective", "mae_occupancy") and value is not None:
                errors[key.removeprefix("mae_")].append(float(value))
    return {measure: float(np.median(values)) for measure, values in sorted(errors.items())}


def realized_over_expected(run: dict) -> float | None:
    """QD-score an expected-gain selection's picks added, over what it expected (``selection_expected_gain``),
    summed over every iteration but the last (which the budget may cut short); None for a run without one."""
    expected = realized = 0.0
    for previous, row in zip(run["history"][:-1], run["history"][1:-1]):
        gain = row.get("selection_expected_gain")
        if gain is None:
            continue
        expected += gain
        realized += row["qd_score"] - previous["qd_score"]
    return realized / expected if expected > 0 else None


def counting_bound(run: dict, baseline_run: dict, clock: str) -> dict[str, float]:
    """How far ``run`` could get at equal time if every evaluation it made had filled a new archive cell.

    One evaluation adds at most one elite, so a run's QD-score is at most its evaluations times the
    QD-score per elite (1 in the Maze, whose objective is 1 on every valid level). Read at the second
    ``run`` ended, against the baseline's QD-score then.

    Returns:
        ``baseline_qd`` then; ``ratio`` (the run's final QD-score over it); ``perfect`` (its evaluations,
        each a new elite); ``perfect_free`` (the same with the surrogate free: as many evaluations as its
        evaluation seconds per level allow in that time); ``yield`` (new elites per evaluation now).
    """
    history = run["history"]
    end, last = run_end(run, clock), history[-1]
    per_elite = last["qd_score"] / max(last.get("num_elites", last["qd_score"]), 1e-9)
    seconds_per_evaluation = run_end(run, clock, evaluation_only=True) / max(last["evals"], 1)
    baseline_qd = max(qd_at_time(baseline_run["history"], end, clock), 1e-9)
    return {"baseline_qd": baseline_qd, "ratio": last["qd_score"] / baseline_qd,
            "perfect": last["evals"] * per_elite / baseline_qd,
            "perfect_free": end / max(seconds_per_evaluation, 1e-9) * per_elite / baseline_qd,
            "yield": last.get("num_elites", last["qd_score"]) / max(last["evals"], 1)}


def is_pipelined(group: list[dict]) -> bool:
    """Whether these runs chose their next picks while a batch was out (``pipeline = true``)."""
    return any("time_overlapped" in row for run in group for row in run["history"])


def print_counting_bound(variant: str, group: list[dict], baseline: list[dict], clock: str, target: float) -> None:
    """Per seed, :func:`counting_bound`, and the share of evaluations that would have to fill a new cell."""
    rows = [(run["seed"], counting_bound(run, other, clock)) for run, other in same_seed_pairs(group, baseline)]
    # A pipelined run's evaluate column is only its wait for the simulators: no surrogate-free reading.
    pipelined = is_pipelined(group)
    for seed, bound in rows:
        print(f"  seed {seed}: now {bound['ratio']:.2f}x with {bound['yield']:.0%} of its evaluations filling a new "
              f"cell; every one filling one: {bound['perfect']:.2f}x"
              + ("" if pipelined else f"; and the surrogate free: {bound['perfect_free']:.2f}x"))
    if rows:
        readings = [("perfect", "every evaluation a new cell")]
        if not pipelined:
            readings.append(("perfect_free", "every evaluation a new cell, surrogate free"))
        for key, what in readings:
            values = [bound[key] for _, bound in rows]
            needed = [target / bound[key] for _, bound in rows]
            print(f"{variant} / baseline at equal {clock} time, {what}: at most {mean_pm(values, '.2f')}x; "
                  f"{target}x needs {mean_pm([100 * n for n in needed], '.0f')}% of its evaluations to fill a "
                  f"new cell")


def print_pairs(variant: str, baseline: str, pairs: list[tuple[int, float, float, bool]], what: str) -> None:
    """One line per seed and the mean ratio (± s.e. over seeds) of :func:`paired_at_own_end`'s pairs."""
    if not pairs:
        print(f"{variant}: no seed shared with {baseline}")
        return
    ratios = [own / max(base, 1e-9) for _, own, base, _ in pairs]
    for (seed, own, base, long_enough), ratio in zip(pairs, ratios):
        note = "" if long_enough else f" ({baseline} stopped before this second: give it a larger budget)"
        print(f"  seed {seed}: {own:,.1f} vs {base:,.1f} → {ratio:.2f}x{note}")
    print(f"{variant} / {baseline} at each {variant} run's own end ({what}): {mean_pm(ratios, '.2f')}x "
          f"over {len(ratios)} seeds ({variant} {mean_pm([own for _, own, _, _ in pairs])} vs {baseline} "
          f"{mean_pm([base for _, _, base, _ in pairs])})")


def print_screen_equivalents(variant: str, baseline: str, runs: list[dict], baselines: list[dict],
                             at_evals: float) -> None:
    """The equal-evaluation reading with a screened run's screens counted as evaluations: each screened level as
    ``selection.screen_episodes / episodes`` of one, the baseline read at the evaluations plus those."""
    ratios = []
    for run, base in same_seed_pairs(runs, baselines):
        evals = [0.0] + [row["evals"] for row in run["history"]]
        screened = np.cumsum([0.0] + [row.get("selection_screened", 0.0) for row in run["history"]])
        extra = float(np.interp(at_evals, evals, screened)) * run["screen_share"]
        own, base_qd = qd_at_evals(run["history"], at_evals)[0], qd_at_evals(base["history"], at_evals + extra)[0]
        ratios.append(own / max(base_qd, 1e-9))
        print(f"  seed {run['seed']}: its screens cost {extra:,.0f} evaluations' episodes by {at_evals:,.0f} "
              f"evaluations; {own:,.1f} vs {baseline} {base_qd:,.1f} at {at_evals + extra:,.0f} → {ratios[-1]:.2f}x")
    if ratios:
        print(f"{variant} / {baseline} at equal evaluations, its screens counted as evaluations: "
              f"{mean_pm(ratios, '.2f')}x over {len(ratios)} seeds")


def evals_and_time_to(history: list[dict], qd_score: float, clock: str) -> tuple[float, float] | None:
    """Evaluations and evaluation seconds (on ``clock``) at which the run first reached ``qd_score`` (linear
    within an outer iteration), or ``None`` if it never did."""
    previous_evals, previous_qd, previous_eval_time = 0.0, 0.0, 0.0
    for row, eval_time in zip(history, evaluation_ends(history, clock)):
        if row["qd_score"] >= qd_score:
            share = (qd_score - previous_qd) / max(row["qd_score"] - previous_qd, 1e-9)
            return (previous_evals + share * (row["evals"] - previous_evals),
                    previous_eval_time + share * (eval_time - previous_eval_time))
        previous_evals, previous_qd, previous_eval_time = row["evals"], row["qd_score"], eval_time
    return None


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("runs", nargs="+", type=Path, help="finished run folders (config.json + metrics.json)")
    parser.add_argument("--baseline", default="map_elites", help="the variant every other is compared with")
    parser.add_argument("--at-evals", type=float, default=2000, help="evaluations of the equal-evaluation table")
    parser.add_argument("--at-time", type=float, help="seconds of the equal-time table (default: shortest run)")
    parser.add_argument("--clock", choices=["wall", "cpu"], default="wall")
    parser.add_argument("--target", type=float, default=1.4, help="equal-time ratio the counting bound is read "
                                                                  "against (issue 17's 1.4)")
    parser.add_argument("--lengths", type=lambda text: [float(v) for v in text.split(",")], default=[],
                        help="comma-separated budgets (evaluations): the ratios of each run stopped there, to see "
                             "how the equal-time comparison moves with the run's length")
    parser.add_argument("--label", choices=["variant", "name"], default="variant",
                        help="group runs by their config's variant, or by its name (settings of one variant)")
    args = parser.parse_args(argv)

    runs = [load_run(folder) for folder in args.runs if folder.is_dir()]
    by_variant: dict[str, list[dict]] = defaultdict(list)
    for run in runs:
        by_variant[run[args.label]].append(run)
    if args.baseline not in by_variant:
        print(f"no {args.baseline!r} run among the folders given (variants: {sorted(by_variant)})", file=sys.stderr)
        return 2
    at_time = args.at_time or min(run["history"][-1][f"{args.clock}_time"] for run in runs)

    print(f"{len(runs)} runs: " + ", ".join(f"{v} × {len(r)} (seeds {sorted(x['seed'] for x in r)})"
                                           for v, r in sorted(by_variant.items())))
    print(f"\n1-2. QD-score at {args.at_evals:,.0f} evaluations and at {at_time:,.0f} s of {args.clock} time")
    print("| variant | runs | QD at equal evaluations | QD at equal time | coverage then | evaluations done by then |")
    print("|---|---|---|---|---|---|")
    at_evals, at_time_qd = {}, {}
    for variant, group in sorted(by_variant.items()):
        values = [qd_at_evals(run["history"], args.at_evals) for run in group]
        at_evals[variant] = [v for v, _ in values]
        short = sum(not reached for _, reached in values)
        at_time_qd[variant] = [qd_at_time(run["history"], at_time, args.clock) for run in group]
        evals_then = [max([0.0] + [row["evals"] for row in run["history"] if row[f"{args.clock}_time"] <= at_time])
                      for run in group]
        coverage = [100 * qd_at_time(run["history"], at_time, args.clock, key="coverage") for run in group]
        note = f" ({short} stopped short)" if short else ""
        print(f"| {variant} | {len(group)} | {mean_pm(at_evals[variant])}{note} | "
              f"{mean_pm(at_time_qd[variant])} | {mean_pm(coverage, '.2f')}% | {mean_pm(evals_then, ',.0f')} |")
    base_e, base_t = np.mean(at_evals[args.baseline]), np.mean(at_time_qd[args.baseline])
    for variant in sorted(by_variant):
        if variant != args.baseline:
            print(f"{variant} / {args.baseline}: {np.mean(at_evals[variant]) / base_e:.2f}x at equal evaluations, "
                  f"{np.mean(at_time_qd[variant]) / max(base_t, 1e-9):.2f}x at {at_time:,.0f} s of {args.clock} "
                  f"time (a common second; the paired reading below is the fair one)")

    for variant in sorted(by_variant):
        if variant != args.baseline and any(run["screen_share"] for run in by_variant[variant]):
            print_screen_equivalents(variant, args.baseline, by_variant[variant], by_variant[args.baseline],
                                     args.at_evals)

    for variant in sorted(by_variant):
        if variant != args.baseline:
            print_pairs(variant, args.baseline, paired_at_own_end(by_variant[variant], by_variant[args.baseline],
                                                                  args.clock), f"{args.clock} time")
            print_time_to_reach(variant, by_variant[variant], by_variant[args.baseline], args.clock)
            if args.lengths:
                print_by_length(variant, args.baseline, by_variant[variant], by_variant[args.baseline], args.clock,
                                args.lengths)

    surrogate_variants = [v for v, g in by_variant.items()
                          if any("time_exploit" in row for run in g for row in run["history"])]
    if not surrogate_variants:
        return 0
    print(f"\n3. Where the time goes (share of the runs' {args.clock} time)")
    print("| variant | " + " | ".join(PHASES) + " | other | surrogate (train + exploit + select) | "
          "seconds per evaluation (evaluate only) |")
    print("|---|" + "---|" * (len(PHASES) + 3))
    eval_cost = {}
    screening: dict[str, float] = {}
    for variant, group in sorted(by_variant.items()):
        rows = [row for run in group for row in phase_seconds(run["history"], args.clock)]
        totals = {phase: sum(row[phase] for row in rows) for phase in PHASES}
        total = sum(row["total"] for row in rows)
        evals = sum(run["history"][-1]["evals"] for run in group)
        eval_cost[variant] = totals["evaluate"] / max(evals, 1)
        shares = [totals[phase] / max(total, 1e-9) for phase in PHASES]
        surrogate = sum(totals[phase] for phase in ("train", "exploit", "select")) / max(total, 1e-9)
        print(f"| {variant} | " + " | ".join(f"{s:.1%}" for s in shares) + f" | {1 - sum(shares):.1%} | "
              f"{surrogate:.1%} | {eval_cost[variant]:.3f} |")
        screen = sum(row.get("time_screen", 0.0) for run in group for row in run["history"])
        if screen:
            screening[variant] = screen / max(sum(row["time_total"] for run in group for row in run["history"]), 1e-9)
    for variant, share in screening.items():
        print(f"  {variant}: its select column includes screening (selection.screen_episodes), "
              f"{share:.1%} of its wall time")

    pipelined = [v for v in surrogate_variants if is_pipelined(by_variant[v])]
    if pipelined:
        print(f"  pipelined ({', '.join(pipelined)}): the surrogate's phases ran while the simulators evaluated, so "
              "they overlap its evaluate column, which is only the time the driver waited for the simulators")

    print("\nselected-batch error: the surrogate's MAE on the levels it picked, median over outer iterations 3+ "
          "per run, mean ± s.e. over runs")
    for variant in surrogate_variants:
        per_run = [(run["seed"], selected_batch_errors(run)) for run in by_variant[variant]]
        for measure in sorted({m for _, errors in per_run for m in errors}):
            values = [(seed, errors[measure]) for seed, errors in per_run if measure in errors]
            print(f"  {variant} {measure}: {mean_pm([v for _, v in values])} ("
                  + ", ".join(f"seed {seed}: {v:,.1f}" for seed, v in values) + ")")

    calibration = {variant: [(run["seed"], ratio) for run in by_variant[variant]
                             if (ratio := realized_over_expected(run)) is not None] for variant in surrogate_variants}
    if any(calibration.values()):
        print("\nexpected-gain selection: QD-score its picks added / what it expected (every iteration but the last)")
        for variant, values in calibration.items():
            if values:
                print(f"  {variant}: {mean_pm([v for _, v in values], '.2f')} ("
                      + ", ".join(f"seed {seed}: {v:.2f}" for seed, v in values) + ")")

    print("\n4. Why: the surrogate free, and the simulator cost at which it pays for itself")
    baseline = by_variant[args.baseline]
    for variant in surrogate_variants:
        group = by_variant[variant]
        if variant in pipelined:
            print(f"  {variant}: pipelined, its surrogate already runs beside the simulators; no surrogate-free reading")
            continue
        print_pairs(variant, args.baseline, paired_at_own_end(group, baseline, args.clock, evaluation_only=True),
                    "surrogate free: evaluation seconds only; no speed-up of the surrogate can do better")
        target = float(np.mean([run["history"][-1]["qd_score"] for run in group]))
        reached = [evals_and_time_to(run["history"], target, args.clock) for run in baseline]
        if any(r is None for r in reached):
            print(f"  break-even: {args.baseline} did not reach {variant}'s final QD-score {target:,.1f} in every "
                  f"run; give it a longer budget")
            continue
        base_eval_time = float(np.mean([t for _, t in reached]))
        base_other = float(np.mean([run_end(run, args.clock) - run_end(run, args.clock, evaluation_only=True)
                                    for run in baseline]))
        base_other *= float(np.mean([e for e, _ in reached])) / float(np.mean([r["history"][-1]["evals"]
                                                                                for r in baseline]))
        own_eval_time = float(np.mean([run_end(run, args.clock, evaluation_only=True) for run in group]))
        own_other = float(np.mean([run_end(run, args.clock) - run_end(run, args.clock, evaluation_only=True)
                                   for run in group]))
        gap = base_eval_time - own_eval_time
        print(f"  to reach {target:,.1f}: {variant} {own_eval_time:,.0f} s evaluating + {own_other:,.0f} s else; "
              f"{args.baseline} {base_eval_time:,.0f} s evaluating + {base_other:,.0f} s else")
        if gap <= 0:
            print(f"  break-even: never — {variant}'s evaluations alone cost more than {args.baseline}'s")
        else:
            factor = (own_other - base_other) / gap
            cost = factor * eval_cost[args.baseline]
            print(f"  break-even: at equal time {variant} is ahead once an evaluation costs more than "
                  f"{max(factor, 0):.2f}x this simulator's ({max(cost, 0):.3f} s per {args.baseline} evaluation)")

    print(f"\n5. The counting bound: one evaluation fills at most one cell (read at each run's own end, {args.clock} "
          f"time)")
    for variant in surrogate_variants:
        print_counting_bound(variant, by_variant[variant], baseline, args.clock, args.target)
    return 0


if __name__ == "__main__":
    sys.exit(main())
