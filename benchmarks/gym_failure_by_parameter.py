"""Does an agent's failure depend on the parameters a gym space varies? Failure rate by quarter of each parameter.

Reads the re-evaluated levels of gym audit collections (``collection.json``) and prints, for each parameter, the
correlation of its value with the failure rate and the mean failure rate in each quarter of its values. Give it the
collections of uniform random searches (``--variant dr``): their levels are a sample of the whole space, so the
table says where the agent fails, not where a search looked::

    python benchmarks/gym_failure_by_parameter.py tb_logs/gym_lunarlander_params/dr_t_seed*/collection

A failure rate that is flat across every parameter leaves a search nothing to find: each cell then fails or not by
the luck of its episodes, and the search that fills the most cells finds the most failing ones. The archive line
measures that luck: a cell whose levels fail less than half of their episodes on average (pooled over every
collection given) still counts as failing when one of its levels happened to fail at least half of its own. The last line says
how much of the failure rate the parameters predict together (their interactions too): the leave-one-out R² of the
mean failure rate of each level's nearest levels in the (normalised) parameter space. Near 0, no surrogate can learn
where the agent fails; a surrogate-assisted search then has nothing to exploit.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np


def failure_by_parameter(collections: list[Path]) -> tuple[list[str], np.ndarray, np.ndarray]:
    """The parameters' names, their values ``(n, P)`` and the failure rates ``(n,)`` of every collection's levels."""
    names: list[str] = []
    rows, failure = [], []
    for folder in collections:
        levels = json.loads((folder / "collection.json").read_text())["levels"]
        for level in levels:
            if not names:
                names = sorted(key for key in level if key.startswith("param."))
            rows.append([float(level[name]) for name in names])
            failure.append(float(level["objective"]))
    return names, np.asarray(rows), np.asarray(failure)


def cell_failure(collections: list[Path]) -> tuple[int, dict[tuple[int, ...], list[float]]]:
    """The archive's cell count and, per archive cell, the failure rates of every collection's levels in it (the
    collections must share their archive: measures, ranges and cells)."""
    cells: dict[tuple[int, ...], list[float]] = {}
    archive = None
    for folder in collections:
        collection = json.loads((folder / "collection.json").read_text())
        this = (collection["measures"], collection["measure_ranges"], collection["archive_dims"])
        if archive not in (None, this):
            raise SystemExit(f"{folder}: its archive differs from the first collection's")
        archive = this
        names, ranges, dims = this
        low, high = np.asarray(ranges, dtype=float).T
        for level in collection["levels"]:
            at = np.asarray([level["measures"][name] for name in names], dtype=float)
            cell = np.clip(np.floor((at - low) / (high - low) * dims), 0, np.asarray(dims) - 1).astype(int)
            cells.setdefault(tuple(cell.tolist()), []).append(float(level["objective"]))
    return int(np.prod(archive[2])), cells


def predicted_share(values: np.ndarray, failure: np.ndarray, *, neighbours: int = 15) -> float:
    """Leave-one-out R² of predicting each level's failure rate by the mean of its ``neighbours`` nearest levels
    (Euclidean, each parameter scaled to [0, 1])."""
    span = np.ptp(values, axis=0)
    scaled = (values - values.min(axis=0)) / np.where(span > 0, span, 1.0)
    distance = ((scaled[:, None, :] - scaled[None, :, :]) ** 2).sum(-1)
    np.fill_diagonal(distance, np.inf)
    nearest = np.argsort(distance, axis=1)[:, :neighbours]
    predicted = failure[nearest].mean(axis=1)
    return float(1.0 - ((failure - predicted) ** 2).mean() / failure.var())


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("collections", nargs="+", type=Path, help="audit collection folders")
    args = parser.parse_args(argv)
    names, values, failure = failure_by_parameter(args.collections)
    print(f"{len(failure)} levels from {len(args.collections)} collections; mean failure rate {failure.mean():.2f}")
    print("| parameter | correlation with the failure rate | failure rate by quarter of its values, low to high |")
    print("|---|---|---|")
    for k, name in enumerate(names):
        edges = np.quantile(values[:, k], [0.0, 0.25, 0.5, 0.75, 1.0])
        quarters = np.clip(np.searchsorted(edges, values[:, k], side="right") - 1, 0, 3)
        means = [failure[quarters == q].mean() for q in range(4)]
        ranges = [f"{edges[q]:.3g}..{edges[q + 1]:.3g}: {m:.2f}" for q, m in enumerate(means)]
        print(f"| {name} | {np.corrcoef(values[:, k], failure)[0, 1]:+.2f} | {'; '.join(ranges)} |")
    print(f"share of the failure rate's variance the parameters predict (leave-one-out R², 15 nearest levels): "
          f"{predicted_share(values, failure):.2f}")
    total, cells = cell_failure(args.collections)
    pooled = [np.mean(rates) for rates in cells.values() if len(rates) >= 3]
    counted = sum(max(rates) >= 0.5 for rates in cells.values())
    print(f"archive cells: {len(cells)} of {total} hold a level; of the {len(pooled)} with 3 levels or more, "
          f"{sum(rate >= 0.5 for rate in pooled)} fail at least half of their levels' episodes on average; "
          f"{counted} hold a level that failed at least half of its own")


if __name__ == "__main__":
    main()
