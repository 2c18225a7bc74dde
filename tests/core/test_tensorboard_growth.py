"""TensorBoard's curves within an outer iteration: the archive's numbers as a batch's results arrive."""

from __future__ import annotations

import copy
import math

import numpy as np
import pytest

from dsage_ray.config import RunConfig
from dsage_ray.core.loop import run_locally
from dsage_ray.core.tensorboard_log import GROWTH_POINTS, growth_curve
from dsage_ray.qd.archives import archive_stats, make_archive
from tests.fakes import SMALL_RUN, BitmapDomain
from tests.ray.helpers import tensorboard_scalars


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


def test_a_runs_event_file_holds_more_qd_score_points_than_outer_iterations(tmp_path):
    config = RunConfig.build({**SMALL_RUN, "image_every": 0})
    run_locally(config, out_dir=tmp_path, domain=BitmapDomain(), console=False)
    scalars = tensorboard_scalars(tmp_path, "dsage/")
    iterations = scalars["dsage/outer_iteration"]
    for name in ("qd_score", "coverage", "objective_max"):
        curve = scalars[f"dsage/{name}"]
        assert len(curve) > 2 * len(iterations), name
        steps = [step for step, _ in curve]
        assert steps == sorted(set(steps)), name  # one point per evaluation count, in order
        # Each iteration's own point is the archive's value, as before.
        assert {step for step, _ in iterations} <= set(steps)
    qd = dict(scalars["dsage/qd_score"])
    assert all(b >= a for a, b in zip(list(qd.values()), list(qd.values())[1:]))  # objectives >= 0 here
