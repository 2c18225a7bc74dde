"""A tiny-budget DSAGE Mario run end to end through Tune and the Ray simulator pool (issue 6)."""

import json

import numpy as np
import pandas as pd

from dsage_ray.config import RunConfig
from dsage_ray.ray.experiment import run_experiment
from tests.domains.mario.conftest import needs_java
from tests.ray.helpers import tensorboard_tags


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
