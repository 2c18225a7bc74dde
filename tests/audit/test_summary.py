"""Failure-diversity numbers on collections small enough to check by hand."""

from __future__ import annotations

import numpy as np
import pytest
from ribs.archives import GridArchive

from dsage_ray.audit.summary import failure_summary, format_summary, grid_indices


def _collection(levels, **top):
    """Two measures on [0, 10] × [0, 4] with 10 × 4 cells: one cell per unit."""
    return {"measures": ["a", "b"], "measure_ranges": [[0.0, 10.0], [0.0, 4.0]], "archive_dims": [10, 4],
            "reference": None, "levels": levels, **top}


def _level(success, a, b, **extra):
    return {"success_rate": success, "measures": {"a": a, "b": b}, **extra}


def test_counts_failures_cells_and_cvar():
    levels = [
        _level(0.0, 1.2, 0.5),   # cell (1, 0), never solved
        _level(0.5, 1.9, 0.1),   # cell (1, 0) again: failure rate exactly 0.5 counts, same cell
        _level(0.25, 7.0, 3.9),  # cell (7, 3), failure rate 0.75
        _level(0.75, 3.0, 2.0),  # failure rate 0.25: not a failure cell
        _level(1.0, 5.0, 1.0),
        _level(1.0, 10.0, 4.0),  # upper bound: clipped into the last cell
    ]
    s = failure_summary(_collection(levels))
    assert s == {"levels": 6, "with_failures": 4, "never_solved": 1, "failure_cells": 2, "cvar10": 0.0}
    assert "regressed" not in s


def test_cvar_takes_the_ceiling_of_ten_percent():
    # 11 levels: ceil(1.1) = 2 worst levels, success 0.1 and 0.3 -> 0.2.
    levels = [_level(x, 5.0, 2.0) for x in (0.9, 0.3, 1.0, 0.1, 1.0, 1.0, 1.0, 0.8, 1.0, 1.0, 1.0)]
    assert failure_summary(_collection(levels))["cvar10"] == pytest.approx(0.2)
    # 30 levels: exactly 3 (10 % of 30 in floating point is 3.0000000000000004).
    levels = [_level(x, 5.0, 2.0) for x in [0.0, 0.3, 0.6] + [0.9] * 27]
    assert failure_summary(_collection(levels))["cvar10"] == pytest.approx(0.3)


def test_regression_numbers():
    levels = [_level(0.0, 1.0, 1.0, regression=1.0), _level(0.5, 2.0, 1.0, regression=0.25),
              _level(1.0, 3.0, 1.0, regression=0.0), _level(1.0, 4.0, 1.0, regression=-0.5)]
    s = failure_summary(_collection(levels, reference="builtin:wall_follower"))
    assert s["regressed"] == 2
    assert s["mean_regression_top10"] == 1.0  # ceil(0.4) = 1 level, the largest regression
    assert "2 regressed" in format_summary(s)


def test_empty_collection():
    s = failure_summary(_collection([]))
    assert s == {"levels": 0, "with_failures": 0, "never_solved": 0, "failure_cells": 0, "cvar10": None}
    assert "n/a" in format_summary(s)
    s = failure_summary(_collection([], reference="builtin:random"))
    assert s["regressed"] == 0 and s["mean_regression_top10"] is None


def test_grid_indices_match_a_ribs_grid_archive():
    ranges, dims = [(0.0, 256.0), (-1.5, 2.5)], (256, 37)
    archive = GridArchive(solution_dim=1, dims=dims, ranges=ranges)
    rng = np.random.default_rng(0)
    measures = np.concatenate([
        rng.uniform([-10, -2], [270, 3], size=(500, 2)),  # including values outside the ranges
        np.array([[0.0, -1.5], [256.0, 2.5], [1.0, -1.5 + 4 / 37], [255.9999999, 0.0]]),  # edges
        np.stack([np.arange(0, 257, dtype=float), np.linspace(-1.5, 2.5, 257)], axis=1),  # every boundary
    ])
    ours = grid_indices(measures, ranges=ranges, dims=dims)
    expected = archive.int_to_grid_index(archive.index_of(measures))
    np.testing.assert_array_equal(ours, expected)
    # A fraction measure with 50 cells: 29/50 scales to 28.999999999999996; only the epsilon keeps it in cell 29.
    fractions = (np.arange(51) / 50)[:, None]
    archive = GridArchive(solution_dim=1, dims=(50,), ranges=[(0.0, 1.0)])
    ours = grid_indices(fractions, ranges=[(0.0, 1.0)], dims=(50,))
    np.testing.assert_array_equal(ours, archive.int_to_grid_index(archive.index_of(fractions)))
    assert ours[29, 0] == 29


def test_grid_indices_rejects_mismatched_shapes():
    with pytest.raises(ValueError, match="archive dims"):
        grid_indices(np.zeros((3, 3)), ranges=[(0, 1), (0, 1)], dims=(2, 2))
