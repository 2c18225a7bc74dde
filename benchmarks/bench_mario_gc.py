"""Mario runs with and without JPype's link between Python's and Java's garbage collectors.

JPype asks the JVM for a collection from Python's collections once the process's Python memory passes its marks
(jpype-project/jpype#1197). ``dsage_ray.domains.mario.simulator`` removes that link when it starts the JVM. This runs
the same ``dsage-ray run`` on Mario (``--variant``, ``--search``, the ``cpu`` preset, ``--seconds`` of time budget) in
fresh processes, one after the other: as shipped (unlinked), and with the link left in place. How much the link
costs depends on the Python memory around the episodes: a ``DSAGE`` object run in-process, without the command's
TensorBoard and progress bars, lost little to it. It prints each arm's evaluations,
QD-score and CPU seconds, and the CPU seconds of JPype's "Python Reference Queue" thread and of the main thread (where
the Mario episodes run)::

    LD_PRELOAD=$JAVA_HOME/lib/libjsig.so python benchmarks/bench_mario_gc.py --variant dsage --search auto --seed 106

Run it with nothing else on the machine.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

#: JPype's thread name as Linux shows it (``/proc/*/task/*/comm`` keeps 15 characters).
REFERENCE_THREAD = "Python Referenc"


def _thread_cpu_seconds() -> dict[str, float]:
    """CPU seconds of this process's threads, summed by name."""
    hz, seconds = os.sysconf("SC_CLK_TCK"), {}
    for task in os.listdir("/proc/self/task"):
        with open(f"/proc/self/task/{task}/comm") as comm, open(f"/proc/self/task/{task}/stat") as stat:
            name, fields = comm.read().strip(), stat.read().rsplit(")", 1)[1].split()
        key = "main" if int(task) == os.getpid() else name
        seconds[key] = seconds.get(key, 0.0) + (int(fields[11]) + int(fields[12])) / hz  # utime + stime
    return seconds


def run_arm(*, variant: str, search: str, seed: int, seconds: float, linked: bool, out: Path) -> dict:
    """One arm, in this process: ``dsage-ray run`` as a user runs it (TensorBoard, progress bars and all)."""
    from dsage_ray.cli import main as cli
    from dsage_ray.domains.mario import simulator

    if linked:
        simulator._unlink_garbage_collectors = lambda: None
    code = cli(["run", "experiments/configs/mario_dsage.toml", "--local", "--preset", "cpu", "--out", str(out),
                "--set", f"variant={variant}", "--set", f"search={search}", "--set", f"seed={seed}",
                "--set", "budget=100000", "--time-budget", f"{seconds:g}s"])
    if code:
        raise SystemExit(code)
    threads = _thread_cpu_seconds()
    last = json.loads((out / "metrics.json").read_text())[-1]  # one row per outer iteration
    return {"linked": linked, "evals": int(last["evals"]), "qd_score": last["qd_score"], "cpu_s": last["cpu_time"],
            "reference_thread_s": threads.get(REFERENCE_THREAD, 0.0), "main_thread_s": threads.get("main", 0.0)}


def main(argv: list[str] | None = None) -> list[dict]:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--variant", default="dsage")
    parser.add_argument("--search", default="fixed")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--seconds", type=float, default=100.0, help="each arm's time budget")
    parser.add_argument("--out", type=Path, default=Path("tb_logs/bench_mario_gc"), help="the runs' folders")
    parser.add_argument("--arm", choices=("linked", "unlinked"), help=argparse.SUPPRESS)  # in a child process
    args = parser.parse_args(argv)
    options = {"variant": args.variant, "search": args.search, "seed": args.seed, "seconds": args.seconds}
    if args.arm:
        print(json.dumps(run_arm(**options, linked=args.arm == "linked", out=args.out / args.arm)))
        return []
    rows = []
    for arm in ("unlinked", "linked"):
        child = [sys.executable, __file__, "--arm", arm, "--variant", args.variant, "--search", args.search,
                 "--seed", str(args.seed), "--seconds", str(args.seconds), "--out", str(args.out)]
        rows.append(json.loads(subprocess.run(child, stdout=subprocess.PIPE, text=True, check=True).stdout
                               .strip().splitlines()[-1]))
    print(f"Mario {args.variant}, search {args.search}, seed {args.seed}, {args.seconds:g} s each")
    print(f"{'collectors':10} {'evaluations':>11} {'QD-score':>9} {'CPU s':>6} {'main thread CPU s':>18} "
          f"{'JPype reference thread CPU s':>29}")
    for row in rows:
        print(f"{'linked' if row['linked'] else 'unlinked':10} {row['evals']:11d} {row['qd_score']:9.1f} "
              f"{row['cpu_s']:6.1f} {row['main_thread_s']:18.1f} {row['reference_thread_s']:29.1f}")
    return rows


if __name__ == "__main__":
    main()
