"""The archive's numbers within an outer iteration, as a batch's results arrive (dsage_ray.qd.growth)."""

from __future__ import annotations

import copy
import math

import numpy as np
import pytest

from dsage_ray.qd.archives import archive_stats, make_archive
from dsage_ray.qd.growth import GROWTH_POINTS, growth_curve


def archive_with(objective, measures):
    archive = make_archive(solution_dim=2, dims=(4, 4), ranges=[(0.0, 1.0), (0.0, 1.0)])
    if len(objective):
        archive.add(np.zeros((len(objective), 2)), np.asarray(objective, float), np.asarray(measures, float))
    return archive


def test_growth_curve_is_the_archive_after_each_result_entered_one_at_a_time_and_changes_nothing():
    archive = archive_with([1.0, 2.0], [[0.1, 0.1], [0.9, 0.9]])
    rng = np.random.default_rng(0)
    measures, objective = rng.random((12, 2)), rng.random(12) * 3
    before = copy.deepcopy(archive_stats(archive))
    points = growth_curve(archive, measures=measures, objective=objective, evals_at=range(11, 23), budget=10)
    assert archive_stats(archive) == before  # read only

    one_by_one = copy.deepcopy(archive)
    assert [p.evals for p in points] == list(range(11, 23))
    for point, m, o in zip(points, measures, objective):
        one_by_one.add(np.zeros((1, 2)), np.array([o]), m[None])
        stats = archive_stats(one_by_one)
        assert point.qd_score == pytest.approx(stats["qd_score"])
        assert point.coverage == pytest.approx(stats["coverage"])
        assert point.objective_max == pytest.approx(stats["objective_max"])


def test_growth_curve_spaces_its_points_over_the_budget_and_starts_from_an_empty_archive():
    budget = 4 * GROWTH_POINTS  # a point every 4 evaluations
    points = growth_curve(archive_with([], []), measures=np.full((10, 2), 0.5), objective=np.arange(10.0),
                          evals_at=range(1, 11), budget=budget)
    assert [p.evals for p in points] == [4, 8]
    assert [p.qd_score for p in points] == [3.0, 7.0] and [p.objective_max for p in points] == [3.0, 7.0]
    assert math.isclose(points[0].coverage, 1 / 16)
    assert growth_curve(archive_with([], []), measures=np.zeros((0, 2)), objective=np.zeros(0), evals_at=[],
                        budget=budget) == ()
