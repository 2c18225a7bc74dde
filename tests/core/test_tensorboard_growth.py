"""TensorBoard's curves within an outer iteration: a run's event file holds the archive's numbers as a batch's
results arrive (the numbers themselves: tests/qd/test_growth.py)."""

from __future__ import annotations

from dsage_ray.config import RunConfig
from dsage_ray.core.loop import run_locally
from tests.fakes import SMALL_RUN, BitmapDomain
from tests.ray.helpers import tensorboard_scalars


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
