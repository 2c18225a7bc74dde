"""Searches side by side at equal evaluations AND equal compute: each (setting, seed) one run, then the tables.

    python experiments/equal_compute.py --out /work/runs/eq --seeds 10,11,12 \\
        --setting dsage:variant=dsage,surrogate.channels=16 --setting map_elites:variant=map_elites \\
        --budget 2000 --parallel 2

Every run is ``dsage_ray.run(..., local=True)``: one process, one thread for the surrogate
(``torch_threads = 1``) and in-process evaluation, so a run's ``cpu_time`` is all the compute it used,
whatever else the machine is doing. That makes ``--clock cpu`` the fair clock on a shared machine
(``--parallel 2`` runs two at a time on 2 cores); on a quiet machine with ``--parallel 1`` the wall
clock reads the same. With ``--workers N`` each run goes through Ray Tune with N simulator actors
instead (the set-up a pipelined outer loop, ``pipeline=true``, is for); the actors' CPU is not in
``cpu_time`` then, so read ``--clock wall`` of runs made one at a time on an otherwise idle machine.
A setting is ``LABEL:key=value,key=value`` on top of ``--preset`` (values read
like ``--set`` values); the label names the run's config (``name``), so the tables group by it.

Runs that already finished end at once and interrupted ones resume, so the command can be re-run
with more seeds or settings. The tables are ``benchmarks/bench_equal_compute.py``'s: QD-score at
equal evaluations and at equal time, where the time goes, and the simulator cost at which the
surrogate pays for itself.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CONFIG = ROOT / "experiments" / "configs" / "maze_dsage.toml"


def parse_setting(text: str) -> tuple[str, list[str]]:
    """``LABEL:k=v,k=v`` → ``(LABEL, ["k=v", "k=v"])``; a comma inside brackets stays in its value."""
    label, _, keys = text.partition(":")
    if not label or not label.replace("_", "").replace("-", "").isalnum():
        raise SystemExit(f"--setting {text!r}: expected LABEL:key=value,... with a plain label")
    items, depth, current = [], 0, ""
    for char in keys:
        depth += char in "[(" 
        depth -= char in "])"
        if char == "," and depth == 0:
            items.append(current)
            current = ""
        else:
            current += char
    return label, [item for item in [*items, current] if item]


def tune_trial_folder(folder: Path) -> Path | None:
    """The finished trial's folder inside a ``--workers`` run's Tune storage folder, if any."""
    finished = sorted(path.parent for path in folder.glob("*/*/metrics.json"))
    return finished[-1] if finished else None


def run_one(label: str, keys: list[str], seed: int, args: argparse.Namespace) -> Path:
    """One run as its own process (so runs in parallel share no torch or Ray state); returns its folder."""
    folder = args.out / f"{label}_s{seed}"
    where = ["--local"] if args.workers is None else ["--workers", str(args.workers)]
    command = [sys.executable, "-m", "dsage_ray.cli", "run", str(args.config), *where, "--preset", args.preset,
               "--out", str(folder), "--set", f"name={label}", "--set", f"seed={seed}",
               *([f"--set=budget={args.budget}"] if args.budget else []), *(f"--set={key}" for key in keys)]
    if args.time_budget:
        command += ["--time-budget", str(args.time_budget)]
    if args.workers is not None:
        trial = tune_trial_folder(folder)
        if trial is not None:
            print(f"{label} seed {seed}: done before ({trial})", flush=True)
            return trial
    elif (folder / "checkpoint.dsage").exists():
        command.append("--resume")  # a finished run resumes to its end at once and rewrites its outputs
    log = args.out / f"{label}_s{seed}.log"
    with log.open("a") as handle:
        code = subprocess.run(command, stdout=handle, stderr=subprocess.STDOUT, cwd=ROOT,
                              env={**os.environ, "TQDM_DISABLE": "1"}).returncode
    if args.workers is not None:
        folder = tune_trial_folder(folder) or folder
    print(f"{label} seed {seed}: exit {code} ({folder})", flush=True)
    return folder


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--out", type=Path, required=True, help="folder of the runs (one per setting x seed)")
    parser.add_argument("--setting", action="append", required=True, metavar="LABEL:KEY=V,...")
    parser.add_argument("--seeds", default="10,11,12", help="comma-separated seeds (the published tables: 10-14, "
                                                            "seeds no tuning saw)")
    parser.add_argument("--config", type=Path, default=CONFIG)
    parser.add_argument("--preset", default="cpu")
    parser.add_argument("--budget", type=int, help="evaluations per run (default: the preset's)")
    parser.add_argument("--time-budget", help="also stop each run after this long (e.g. 10m)")
    parser.add_argument("--parallel", type=int, default=1, help="runs at a time (each uses one core)")
    parser.add_argument("--baseline", default="map_elites", help="label every other setting is compared with")
    parser.add_argument("--at-evals", type=float, default=2000)
    parser.add_argument("--clock", choices=["wall", "cpu"], default="cpu")
    parser.add_argument("--workers", type=int, help="run each search through Ray Tune with this many simulator "
                                                    "actors instead of in-process (then read --clock wall, "
                                                    "--parallel 1, on a quiet machine)")
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    settings = dict(parse_setting(text) for text in args.setting)
    seeds = [int(seed) for seed in args.seeds.split(",")]

    # 1. Every run, seed-major so that a stopped command leaves every setting with the same seeds done.
    todo = [(label, keys, seed) for seed in seeds for label, keys in settings.items()]
    print(f"{len(todo)} runs ({len(settings)} settings x seeds {seeds}), {args.parallel} at a time, in {args.out}")
    with ThreadPoolExecutor(args.parallel) as pool:
        folders = list(pool.map(lambda job: run_one(*job, args), todo))

    # 2. The tables.
    sys.path.insert(0, str(ROOT / "benchmarks"))
    import bench_equal_compute

    finished = [str(folder) for folder in folders if (folder / "metrics.json").exists()]
    return bench_equal_compute.main([*finished, "--baseline", args.baseline, "--at-evals", str(args.at_evals),
                                     "--clock", args.clock, "--label", "name"])


if __name__ == "__main__":
    sys.exit(main())
