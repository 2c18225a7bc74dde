"""Mario on the Ray simulator pool (a JVM in each actor), and a tiny DSAGE Mario run end to end through Tune (issue 6)."""

import json

import numpy as np
import pandas as pd
import pytest

from dsage_ray.config import RunConfig
from dsage_ray.core.evaluation import InProcessEvaluator
from dsage_ray.domains import build_domain
from dsage_ray.ray.experiment import run_experiment
from dsage_ray.ray.pool import SimulatorPool
from tests.domains.mario.conftest import needs_java
from tests.ray.helpers import tensorboard_tags

TINY = RunConfig.build(domain="mario", variant="dsage", preset="tiny")


@needs_java
def test_levels_played_by_two_pool_actors_equal_the_in_process_results(ray_session):
    domain = build_domain(TINY)
    solutions = domain.random_solutions(2, np.random.default_rng(3))  # one level an actor
    seeds = [11, 12]
    expected = InProcessEvaluator(domain=domain)(solutions, seeds)
    with SimulatorPool(config=TINY, num_workers=2, cpus_per_worker=0.5) as pool:
        results = pool(solutions, seeds)
        assert len({info["pid"] for info in pool.actor_info}) == 2
        assert pool.stats.actor_deaths == 0
    assert not any(r.failed for r in results) and not any(r.failed for r in expected)
    assert [r.objective for r in results] == [r.objective for r in expected]
    assert all(np.array_equal(r.measures, e.measures) for r, e in zip(results, expected))


# Slow (about 60 s on a clean clone): Mario on the pool is the test above, and Tune's path through the Trainable is
# the same for every domain (tests/ray/test_ray_progress.py, test_ray_trainable.py, test_mode_equality.py).
@pytest.mark.slow
@needs_java
def test_tiny_mario_dsage_through_tune_and_the_pool(ray_session, tmp_path):
    # Images once, when the budget is spent: rendering Mario's levels costs seconds, and once shows they arrive.
    # 8 evaluations: the 6 random levels and two surrogate iterations (each outer iteration costs about 3 s).
    config = RunConfig.build(domain="mario", variant="dsage", preset="tiny", image_every=100, budget=8,
                             **{"ray.num_workers": 2, "ray.cpus_per_worker": 0.5, "ray.trial_cpus": 0.5})
    (trial,) = run_experiment(config.to_flat(), name="mario_tiny", storage_path=tmp_path, max_failures=0,
                              verbose=0).trials
    trial_dir = trial.path

    metrics = json.loads((trial_dir / "metrics.json").read_text())
    assert metrics[-1]["evals"] == config.budget and json.loads((trial_dir / "failures.json").read_text()) == []
    assert metrics[-1]["qd_score"] > 0
    archive = pd.read_csv(trial_dir / "archive.csv")
    assert len(archive) >= 1 and archive["objective"].between(0, 1).all()
    assert np.all(archive.filter(like="measures_").to_numpy() >= 0)

    scalars, images = tensorboard_tags(trial_dir)
    assert "dsage/qd_score" in scalars and not any(tag.startswith("ray/tune/") for tag in scalars)
    # The heatmap and sample levels (rendered with Mario's path) reach TensorBoard.
    assert {"archive/heatmap", "levels/elite_0"} <= images
