"""Pools the per-audit rows of several ``audit_comparison.py`` tables (other seeds of the same comparison).

    python benchmarks/pool_audit_tables.py docs/results/gym_audit/lunarlander_seeds_180_182.md \
        docs/results/gym_audit/lunarlander_seeds_190_192.md --reference dsage

For each arm: mean ± standard error over every seed of every table, of the failing cells and the worst return;
then, for each other arm, the paired difference (reference − arm) over the seeds both hold, with how many seeds it
is below zero, and for the cells the reference's ratio of the means over those seeds and its ratio on each seed.
The tables are read, not the audits, so a comparison whose audit folders are gone can still be pooled with a later
one; each table's "Per audit" rows are its numbers.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from metrics import format_mean_se, mean_se

#: The columns pooled: (heading in the table, short name printed, whether a ratio of means means something).
POOLED = (("Cells with failure rate ≥ 0.5", "failing cells", True), ("Worst return", "worst return", False))


def per_audit_rows(text: str) -> list[dict[str, str]]:
    """The rows of a table's "Per audit" section, each ``{heading: cell}``.

    Raises:
        ValueError: The text has no "Per audit" table.
    """
    lines = text.split("Per audit:", 1)[-1].strip().splitlines() if "Per audit:" in text else []
    table = [line for line in lines if line.startswith("|")]
    if len(table) < 2:
        raise ValueError("no 'Per audit:' table (is it a table audit_comparison.py wrote?)")
    headings = [cell.strip() for cell in table[0].strip("|").split("|")]
    return [dict(zip(headings, (cell.strip() for cell in row.strip("|").split("|")))) for row in table[2:]]


def pooled(paths: list[Path]) -> dict[str, dict[int, dict[str, float]]]:
    """``{arm: {seed: {heading: value}}}`` over the tables; a seed in two tables is refused."""
    arms: dict[str, dict[int, dict[str, float]]] = {}
    for path in paths:
        for row in per_audit_rows(path.read_text()):
            seed = int(row["Seed"])
            runs = arms.setdefault(row["Variant"], {})
            if seed in runs:
                raise ValueError(f"{path}: {row['Variant']} seed {seed} is in another table too")
            missing = [heading for heading, *_ in POOLED if heading not in row]
            if missing:
                raise ValueError(f"{path}: no column {', '.join(map(repr, missing))} in its 'Per audit' table")
            runs[seed] = {heading: float(row[heading].replace(",", "")) for heading, *_ in POOLED}
    return arms


def report(arms: dict[str, dict[int, dict[str, float]]], reference: str) -> str:
    if reference not in arms:
        raise ValueError(f"--reference {reference!r} is not an arm (arms: {', '.join(arms)})")
    lines = []
    for heading, name, has_ratio in POOLED:
        lines.append(f"{name}:")
        for arm, runs in arms.items():
            mean, se = mean_se(run[heading] for run in runs.values())
            line = f"  {arm:<18} {format_mean_se(mean, se, ',.1f'):>16}  ({len(runs)} seeds)"
            seeds = sorted(set(runs) & set(arms[reference]))
            if arm != reference and seeds:
                ours = [arms[reference][s][heading] for s in seeds]
                theirs = [runs[s][heading] for s in seeds]
                diff = [a - b for a, b in zip(ours, theirs)]
                gap, gap_se = mean_se(diff)
                line += (f"  {reference} − {arm} {gap:+,.1f} ± {gap_se:,.1f} paired "
                         f"(below 0 on {sum(d < 0 for d in diff)} of {len(diff)} seeds)")
                if has_ratio and all(theirs):
                    per_seed = ", ".join(f"{a / b:.2f}" for a, b in zip(ours, theirs))
                    line += f"; {reference} {sum(ours) / sum(theirs):.2f}× (per seed {per_seed})"
            lines.append(line)
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("tables", nargs="+", type=Path, help="summary.md files of audit_comparison.py")
    parser.add_argument("--reference", default="dsage", help="the arm the others are compared with (default dsage)")
    args = parser.parse_args(argv)
    try:
        print(report(pooled(args.tables), args.reference))
    except (OSError, ValueError) as exc:
        print(f"pool_audit_tables: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
