"""How many faults and fault cells a peers' task holds at all: the ceiling under every search's counts (issue 62).

A search cannot find more fault cells than the task's grid holds faults in. This plays, through the same
:class:`~peer_comparison.Ledger` every arm plays through, either every level of the task (when each parameter is an
integer or a choice and they number at most ``--levels``: Taxi's 25,740) or a scrambled Sobol sample of
``--levels`` levels of the box, and prints the faults and fault cells it found; with ``--records``, also the union of
the fault cells the runs in those files found, and how many of them the sample missed::

    python benchmarks/fault_ceiling.py --task taxi
    python benchmarks/fault_ceiling.py --task cartpole --levels 8192 --records docs/results/peers/cp_fresh*.jsonl.gz
"""

from __future__ import annotations

import argparse
import itertools
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from peer_comparison import TASKS, Config, Ledger, load_records, make_domain  # noqa: E402  (this folder's)


def levels_of(space, *, levels: int, seed: int) -> tuple[np.ndarray, str]:
    """Every level of an integer space of at most ``levels`` levels, else a Sobol sample; and what it is."""
    params = space.params
    if all(p.kind != "float" for p in params):
        values = [range(int(p.low), int(p.high) + 1) for p in params]
        total = int(np.prod([len(v) for v in values]))
        if total <= levels:
            grid = np.array(list(itertools.product(*values)), dtype=float)
            low, high = np.array([p.low for p in params]), np.array([p.high for p in params])
            return 2.0 * (grid - low) / (high - low) - 1.0, f"every level ({total:,})"
    from scipy.stats import qmc

    sample = qmc.Sobol(d=len(params), scramble=True, seed=seed).random(levels)
    return 2.0 * sample - 1.0, f"a scrambled Sobol sample of {levels:,} levels (seed {seed})"


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--task", choices=sorted(TASKS), required=True)
    parser.add_argument("--agent", help="the task's agent (default: the task's)")
    parser.add_argument("--levels", type=int, default=30_000)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--records", nargs="*", type=Path, default=[])
    args = parser.parse_args(argv)
    task = TASKS[args.task]
    config = Config(task=args.task, agent=args.agent or task["agent"], space=task["space"],
                    env_args=tuple(task.get("env_args", ())))
    domain = make_domain(config)
    levels, what = levels_of(domain.space, levels=args.levels, seed=args.seed)
    ledger = Ledger(domain=domain, episodes=len(levels))
    try:
        from tqdm import tqdm
    except ImportError:  # tqdm comes with mdpfuzz (the peers extra); without it, no bar
        def tqdm(x, **_):
            return x
    for level in tqdm(levels, desc="levels", unit="level"):
        ledger.play(level)
    faults = [row for row in ledger.trace if row["fault"]]
    cells = {tuple(row["cell"]) for row in faults}
    print(f"{args.task}, {config.agent}: {what}: {len(faults):,} faults ({100 * len(faults) / len(levels):.2f}%) "
          f"in {len(cells)} fault cells; {len({tuple(r['cell']) for r in ledger.trace})} cells covered; "
          f"{ledger.trace[-1]['cpu']:.0f} CPU s")
    if args.records:
        runs = load_records(args.records)
        found = {tuple(row["cell"]) for run in runs for row in run["trace"] if row["fault"]}
        print(f"the {len(runs)} runs in {', '.join(map(str, args.records))}: {len(found)} fault cells together; "
              f"with this sample {len(found | cells)}; {len(found - cells)} of theirs not in this sample")


if __name__ == "__main__":
    main()
