"""Which search finds the most diverse failures? ``dsage-ray audit`` per variant × seed, one table.

    python experiments/audit_comparison.py --agent dcd:accel --preset cpu --seeds 3
    python experiments/audit_comparison.py --agent builtin:wall_follower --preset tiny --seeds 1 --variants dsage,dr
    python experiments/audit_comparison.py --out tb_logs/audit_comparison --summary-only   # the table again
    python experiments/audit_comparison.py --variants cold=dsage,warm=dsage --arm-set warm:surrogate.init=FILE \
        --first-seed 200 --budget 500 --out tb_logs/warm_start          # the same search, cold and warm-started
    python experiments/audit_comparison.py --variants dsage,map_elites --budget 100000 --set time_budget=360 \
        --match-time map_elites --first-seed 10 --out tb_logs/equal_time   # equal search time, not evaluations

Every (arm, seed) is one audit (``dsage-ray audit --local --variant V --seed K``) in ``OUT/V_seedK``:
the same agent, objective, measures and budget, and a collection whose elites are all re-evaluated
with recorded seeds, so the counts compare searches, not the luck of the search's own episodes. The
table (``OUT/summary.md``: mean ± standard error over seeds, then every audit's own row) holds the
failure-diversity numbers of each collection (``dsage_ray.audit.summary``): never-solved levels, distinct
archive cells with a level failing at least half the time, levels with any failure. Audits run ``--jobs``
at a time, each in its own process on one thread; one already collected is skipped and an interrupted one
resumes, so the command can be run again after a stop. ``--episodes N`` re-evaluates each collection with N
episodes per level: give a search that plays few episodes per level (``gym.episodes=3``) a steadier count, and
run again with it to re-collect finished audits without searching again. An arm is a variant, or
``LABEL=VARIANT`` with its own config keys (``--arm-set LABEL:KEY=VALUE``), so one search can be compared with
itself under other settings; its folders and rows are named by the label. The table also gives each search's wall time
(minutes of its ``wall_time``: compare it only on a quiet machine at ``--jobs 1``) and its CPU seconds (the
search process's ``cpu_time``, evaluation included: the clock to compare when audits share the machine).

**Equal time.** A time budget ends a search when it is reached, but a search can still overshoot it by the
surrogate's phases if the time runs out during them (the comparisons in ``docs/results/equal_compute`` ran when a
time budget stopped a search only after the whole outer iteration that reached it).
``--match-time LABEL`` (repeatable) therefore runs the other arms first and gives each of LABEL's audits the
time its seed's first other arm actually searched (its final ``wall_time``) as ``time_budget``; give every arm
an evaluation ``--budget`` it cannot reach. Audits run seed by seed, so those side by side share the machine
alike.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

#: benchmarks/, where the result tables' figures (``metrics.py``) live.
BENCHMARKS = Path(__file__).resolve().parents[1] / "benchmarks"
#: The columns of the table: (summary key, heading).
COLUMNS = (("never_solved", "Never solved"), ("failure_cells", "Cells with failure rate ≥ 0.5"),
           ("with_failures", "Levels with failures"), ("levels", "Levels"), ("worst_return", "Worst return"),
           ("evaluations", "Evaluations"), ("search_minutes", "Search minutes"),
           ("search_cpu_s", "Search CPU seconds"))


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--agent", default="dcd:accel", help="agent spec to audit (default dcd:accel)")
    parser.add_argument("--domain", default="maze")
    parser.add_argument("--preset", default="cpu")
    parser.add_argument("--variants", default="dsage,map_elites,dr",
                        help="comma-separated searches to compare: VARIANT or LABEL=VARIANT")
    parser.add_argument("--arm-set", action="append", default=[], metavar="LABEL:KEY=VALUE",
                        help="a config key for one arm only, e.g. warm:surrogate.init=tb_logs/accel.surrogate")
    parser.add_argument("--seeds", type=int, default=3, help="seeds per arm (default 3)")
    parser.add_argument("--first-seed", type=int, default=0, help="the first seed (default 0: seeds 0..K-1)")
    parser.add_argument("--budget", type=int, help="real evaluations per search (default: the preset's)")
    parser.add_argument("--jobs", type=int, default=2, help="audits at a time (one CPU each)")
    parser.add_argument("--out", type=Path, default=Path("tb_logs/audit_comparison"))
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                        help="any config key, for every audit")
    parser.add_argument("--match-time", action="append", default=[], metavar="LABEL",
                        help="run LABEL's audits with the time that the same seed's first other arm searched as "
                             "their time_budget (module docstring, 'Equal time')")
    parser.add_argument("--episodes", type=int,
                        help="episodes per level in each collection's re-evaluation (default: the config's, e.g. "
                             "gym.episodes); an audit collected with another number is collected again from its "
                             "finished search, which is not re-run")
    parser.add_argument("--summary-only", action="store_true", help="only write the table from finished audits")
    return parser.parse_args(argv)


def parse_arms(args: argparse.Namespace) -> dict[str, str]:
    """``{label: variant}`` of ``--variants``, in order; every ``--arm-set`` label must be one of them."""
    arms: dict[str, str] = {}
    for item in (v.strip() for v in args.variants.split(",")):
        if item:
            label, _, variant = item.rpartition("=")
            arms[label or variant] = variant
    for item in args.arm_set:
        label, sep, _ = item.partition(":")
        if not sep or label not in arms:
            raise SystemExit(f"--arm-set {item!r}: expected LABEL:KEY=VALUE with LABEL one of {sorted(arms)}")
    for label in args.match_time:
        if label not in arms:
            raise SystemExit(f"--match-time {label!r}: not an arm (arms: {sorted(arms)})")
    if args.match_time and not set(arms) - set(args.match_time):
        raise SystemExit("--match-time: at least one arm must keep its own time (the reference)")
    return arms


def seeds(args: argparse.Namespace) -> list[int]:
    return list(range(args.first_seed, args.first_seed + args.seeds))


def reference_time(args: argparse.Namespace, seed: int) -> float:
    """Seconds the seed's reference search stepped (``--match-time``): the first arm not matched."""
    reference = next(label for label in parse_arms(args) if label not in args.match_time)
    seconds = search_time(collection_file(args.out, reference, seed).parent)["search_minutes"] * 60
    if not seconds == seconds:  # NaN: the reference has no metrics
        raise SystemExit(f"--match-time: the {reference} audit of seed {seed} has no search metrics in {args.out}")
    return seconds


def audit_command(args: argparse.Namespace, label: str, seed: int, folder: Path) -> list[str]:
    """The ``dsage-ray audit`` command of one grid point (resuming its search if one was started)."""
    variant = parse_arms(args)[label]
    command = [sys.executable, "-m", "dsage_ray.cli", "audit", "--local", "--domain", args.domain,
               "--agent", args.agent, "--preset", args.preset, "--variant", variant, "--seed", str(seed),
               "--out", str(folder)]
    if args.budget is not None:
        command += ["--budget", str(args.budget)]
    arm_keys = [item.partition(":")[2] for item in args.arm_set if item.partition(":")[0] == label]
    keys = [*args.overrides, *arm_keys]
    if not any(item.partition("=")[0].strip() == "search" for item in keys):
        # Each arm is the search it names: an audit with a time budget would otherwise search with auto.
        keys.insert(0, "search=fixed")
    for item in keys:
        command += ["--set", item]
    if label in args.match_time:
        command += ["--set", f"time_budget={reference_time(args, seed):.1f}"]
    if args.episodes is not None:
        command += ["--episodes", str(args.episodes)]
    if (folder / "collection" / "collection.json").is_file():
        command.append("--collect-only")  # only the re-evaluation's episodes differ (see to_run)
    elif (folder / "search").is_dir():
        command.append("--resume")
    return command


def collected_episodes(out: Path, variant: str, seed: int) -> int | None:
    """Episodes per level of the audit's collection re-evaluation; None when it has no collection yet."""
    try:
        return int(json.loads(collection_file(out, variant, seed).read_text())["episodes"])
    except (OSError, ValueError, KeyError, TypeError):
        return None


def to_run(args: argparse.Namespace, variant: str, seed: int) -> bool:
    """Whether the grid point still needs its audit: no collection, or one re-evaluated with other ``--episodes``."""
    episodes = collected_episodes(args.out, variant, seed)
    return episodes is None or (args.episodes is not None and episodes != args.episodes)


def run_audit(args: argparse.Namespace, variant: str, seed: int) -> tuple[str, int, int, float]:
    """Runs one audit to completion (output to ``OUT/V_seedK.log``); returns its exit code and seconds."""
    folder = args.out / f"{variant}_seed{seed}"
    log = args.out / f"{variant}_seed{seed}.log"
    env = {**os.environ, "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
    started = time.perf_counter()
    with log.open("a") as stream:
        code = subprocess.run(audit_command(args, variant, seed, folder), stdout=stream, stderr=subprocess.STDOUT,
                              env=env, check=False).returncode
    return variant, seed, code, time.perf_counter() - started


def collection_file(out: Path, variant: str, seed: int) -> Path:
    return out / f"{variant}_seed{seed}" / "collection" / "collection.json"


def search_time(collection_dir: Path) -> dict[str, float]:
    """The audit's search time: minutes it stepped (its last ``wall_time``) and the CPU seconds of its process
    (``cpu_time``: the fair clock when audits share the machine, as ``--local`` evaluates in that process);
    NaN when its metrics are not there."""
    metrics = collection_dir.parent / "search" / "metrics.json"
    try:
        last = json.loads(metrics.read_text())[-1]
        return {"search_minutes": float(last["wall_time"]) / 60, "search_cpu_s": float(last["cpu_time"]),
                "evaluations": float(last.get("evals", "nan"))}
    except (OSError, ValueError, KeyError, IndexError):
        return {"search_minutes": float("nan"), "search_cpu_s": float("nan"), "evaluations": float("nan")}


def shown_columns(per_run: dict[str, list[dict]]) -> list[tuple[str, str]]:
    """The columns every audit has a number for (``worst_return`` only where the domain records returns)."""
    runs = [run for summaries in per_run.values() for run in summaries]
    return [(key, title) for key, title in COLUMNS if runs and all(run.get(key) is not None for run in runs)]


def summarize(out: Path, variants: list[str], seeds: list[int]) -> str:
    """The markdown table over the finished audits in ``out`` (mean ± s.e. over seeds per arm)."""
    from dsage_ray.audit.collection_file import load_collection
    from dsage_ray.audit.summary import failure_summary

    if str(BENCHMARKS) not in sys.path:  # the result tables' figures are research code kept with the benchmarks
        sys.path.insert(0, str(BENCHMARKS))
    from metrics import format_mean_se, mean_se

    per_run: dict[str, list[dict]] = {}
    for variant in variants:
        per_run[variant] = [failure_summary(load_collection(collection_file(out, variant, seed).parent))
                            | {"seed": seed, **search_time(collection_file(out, variant, seed).parent)}
                            for seed in seeds if collection_file(out, variant, seed).is_file()]
    columns = shown_columns(per_run)
    lines = ["| Variant | Audits | " + " | ".join(title for _, title in columns) + " |",
             "|---" * (len(columns) + 2) + "|"]
    for variant, summaries in per_run.items():
        if not summaries:
            continue
        cells = [format_mean_se(*mean_se(s[key] for s in summaries), ",.1f") for key, _ in columns]
        lines.append(f"| {variant} | {len(summaries)} | " + " | ".join(cells) + " |")
    (out / "summary.json").write_text(json.dumps(per_run, indent=1))
    return "\n".join(lines) + "\n\nPer audit:\n\n" + per_seed_table(per_run)


def per_seed_table(per_run: dict[str, list[dict]]) -> str:
    """Every audit's own numbers, a row per arm and seed, so that what holds on each seed is printed too."""
    columns = shown_columns(per_run)
    lines = ["| Variant | Seed | " + " | ".join(title for _, title in columns) + " |", "|---" * (len(columns) + 2) + "|"]
    for variant, summaries in per_run.items():
        for run in summaries:
            cells = [f"{float(run[key]):,.{1 if key == 'search_minutes' else 0}f}" for key, _ in columns]
            lines.append(f"| {variant} | {run['seed']} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def episodes_note(args: argparse.Namespace, variants: list[str]) -> str:
    """`` and N episodes`` of the collections' re-evaluations (each count, when they differ)."""
    counts = sorted({e for v in variants for s in seeds(args) if (e := collected_episodes(args.out, v, s))})
    return f" and {' or '.join(map(str, counts))} episodes" if counts else ""


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    variants = list(parse_arms(args))
    args.out.mkdir(parents=True, exist_ok=True)
    if not args.summary_only:
        # Seed by seed, so that the arms running side by side share the machine alike; matched arms last.
        todo = [(v, s) for matched in (False, True) for s in seeds(args) for v in variants
                if (v in args.match_time) == matched and to_run(args, v, s)]
        again = sum(collected_episodes(args.out, v, s) is not None for v, s in todo)
        print(f"{len(todo)} audits to run ({len(variants)} variants × {args.seeds} seeds, "
              f"{len(variants) * args.seeds - len(todo)} already collected"
              + (f", {again} to collect again with {args.episodes} episodes" if again else "")
              + f"), {args.jobs} at a time; logs in {args.out}")
        failed = []
        for matched in (False, True):
            phase = [(v, s) for v, s in todo if (v in args.match_time) == matched]
            if matched and failed:
                break  # a matched arm needs its reference
            with ThreadPoolExecutor(max_workers=max(1, args.jobs)) as pool:
                for variant, seed, code, seconds in pool.map(lambda point: run_audit(args, *point), phase):
                    status = "done" if code == 0 else f"FAILED (exit {code})"
                    print(f"  {variant} seed {seed}: {status} in {seconds / 60:.1f} min "
                          f"({args.out / f'{variant}_seed{seed}.log'})", flush=True)
                    if code != 0:
                        failed.append((variant, seed))
        if failed:
            print(f"{len(failed)} audits failed; run the command again to resume them", file=sys.stderr)
    table = summarize(args.out, variants, seeds(args))
    (args.out / "summary.md").write_text(
        f"{table}\n\nAgent `{args.agent}`, preset `{args.preset}`"
        + (f", budget {args.budget}" if args.budget else "")
        + "".join(f", {item}" for item in args.arm_set)
        + "".join(f", {label} given the time of the same seed's reference search" for label in args.match_time)
        + f", seeds {args.first_seed}..{args.first_seed + args.seeds - 1}; mean ± standard error over seeds. Every "
          "level of a collection was re-evaluated with its recorded seed"
        + episodes_note(args, variants) + ".\n")
    print(table)
    print(f"table: {args.out / 'summary.md'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
