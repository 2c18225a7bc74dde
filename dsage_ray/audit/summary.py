"""How diverse are the failures of a collection? A handful of numbers the CLI prints and the report shows.

The numbers (the contract is ``COLLECTION_SCHEMA``'s "Summary numbers"):

- ``levels``: entries in the collection.
- ``with_failures``: levels with ``success_rate < 1`` (at least one failed episode or run).
- ``never_solved``: levels with ``success_rate == 0``.
- ``failure_cells``: distinct archive cells holding at least one level whose failure rate
  ``1 - success_rate`` is at least :data:`FAILURE_CELL_RATE`; cells as a pyribs ``GridArchive`` with the
  collection's ``measure_ranges`` and ``archive_dims`` indexes them (:func:`grid_indices`). Many failures in
  one cell are one kind of failure; many cells are many kinds.
- ``cvar10``: the mean success rate of the worst ``ceil(10 %)`` of levels by success rate (the lower-tail
  CVaR at 10 %); None for an empty collection.
- domains whose entries record ``min_return`` (the gym domain): ``worst_return``, the lowest episode return of
  any level's re-evaluation.
- regression audits only (entries carry ``regression``): ``regressed``, the levels with ``regression > 0``,
  and ``mean_regression_top10``, the mean regression of the ``ceil(10 %)`` levels with the largest
  regression (the same tail as ``cvar10``).
"""

from __future__ import annotations

import math
from typing import Any, Sequence

import numpy as np

#: A cell counts as failing when one of its levels fails at least this often.
FAILURE_CELL_RATE = 0.5
#: The tail fraction of ``cvar10`` and ``mean_regression_top10``.
TAIL = 0.1
#: pyribs' ``GridArchive`` default epsilon, added before truncation against floating-point error.
GRID_EPSILON = 1e-6


def grid_indices(measures: np.ndarray, *, ranges: Sequence[Sequence[float]], dims: Sequence[int]) -> np.ndarray:
    """Grid indices of a batch of measures, exactly as ``ribs.archives.GridArchive.index_of`` computes them.

    A copy of pyribs 0.12's rule (scale into ``[0, dims)``, add epsilon, truncate, clip) rather than a
    throwaway ``GridArchive``, whose storage for a 256 × 648 grid would be allocated only to compute indices.

    Args:
        measures: ``(n, k)`` measure values.
        ranges: ``(low, high)`` per measure.
        dims: Cells per measure.

    Returns:
        ``(n, k)`` int array of per-measure cell indices.
    """
    measures = np.asarray(measures, dtype=np.float64)
    low, high = np.asarray(ranges, dtype=np.float64).T
    dims = np.asarray(dims)
    if measures.ndim != 2 or measures.shape[1] != len(dims) or len(low) != len(dims):
        raise ValueError(f"measures of shape {measures.shape} do not match {len(dims)} archive dims and "
                         f"{len(low)} ranges")
    cells = ((dims * (measures - low) + GRID_EPSILON) / (high - low)).astype(np.int32)
    return np.clip(cells, 0, dims - 1)


def _tail_size(count: int) -> int:
    # ceil on a rounded product: 10 % of 30 levels is 3, not the 4 that float error would give.
    return max(1, math.ceil(round(count * TAIL, 9)))


def failure_summary(collection: dict[str, Any]) -> dict[str, Any]:
    """The failure-diversity numbers of a collection (module docstring).

    Args:
        collection: A loaded ``collection.json``.

    Returns:
        ``{"levels", "with_failures", "never_solved", "failure_cells", "cvar10"}``, plus ``"regressed"`` and
        ``"mean_regression_top10"`` for a regression audit (a ``reference`` agent, entries with ``regression``).
    """
    levels = collection["levels"]
    success = np.array([lv["success_rate"] for lv in levels], dtype=np.float64)
    summary: dict[str, Any] = {
        "levels": len(levels),
        "with_failures": int((success < 1).sum()),
        "never_solved": int((success == 0).sum()),
        "failure_cells": 0,
        "cvar10": None,
    }
    if levels:
        failing = [lv for lv in levels if 1 - lv["success_rate"] >= FAILURE_CELL_RATE]
        if failing:
            names = collection["measures"]
            measures = np.array([[lv["measures"][m] for m in names] for lv in failing], dtype=np.float64)
            cells = grid_indices(measures, ranges=collection["measure_ranges"], dims=collection["archive_dims"])
            summary["failure_cells"] = len({tuple(c) for c in cells.tolist()})
        summary["cvar10"] = float(np.sort(success)[:_tail_size(len(levels))].mean())
    if levels and all("min_return" in lv for lv in levels):
        summary["worst_return"] = float(min(lv["min_return"] for lv in levels))
    if collection.get("reference") is not None or any("regression" in lv for lv in levels):
        regression = np.array([lv["regression"] for lv in levels], dtype=np.float64)
        summary["regressed"] = int((regression > 0).sum())
        summary["mean_regression_top10"] = (
            float(np.sort(regression)[::-1][:_tail_size(len(levels))].mean()) if levels else None)
    return summary


def format_summary(summary: dict[str, Any]) -> str:
    """One line for the terminal, e.g. ``137 levels: 5 with failures, 2 never solved, ...``."""
    cvar = "n/a" if summary["cvar10"] is None else f"{summary['cvar10']:.3f}"
    line = (f"{summary['levels']} levels: {summary['with_failures']} with failures, {summary['never_solved']} never "
            f"solved, {summary['failure_cells']} archive cells with failure rate >= {FAILURE_CELL_RATE:g}, "
            f"mean success of the worst 10% {cvar}")
    if "worst_return" in summary:
        line += f", worst return {summary['worst_return']:.1f}"
    if "regressed" in summary:
        top = summary["mean_regression_top10"]
        line += (f"; {summary['regressed']} regressed, mean regression of the worst 10% "
                 f"{'n/a' if top is None else format(top, '+.3f')}")
    return line
