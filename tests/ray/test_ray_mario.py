"""A tiny-budget DSAGE Mario run end to end through the Ray simulator pool (issue 6)."""

import numpy as np

from dsage_ray.config import RunConfig
from dsage_ray.core.runner import DSAGE
from dsage_ray.domains import build_domain
from dsage_ray.ray.pool import SimulatorPool
from tests.domains.mario.conftest import needs_java


@needs_java
def test_tiny_mario_dsage_through_the_pool(ray_session):
    config = RunConfig.build(domain="mario", variant="dsage", preset="tiny", **{"ray.num_workers": 2})
    with SimulatorPool(config=config) as pool:
        runner = DSAGE(config=config, evaluator=pool, domain=build_domain(config))
        history = runner.run()
    assert runner.evals == config.budget and not runner.failures
    assert history[-1]["qd_score"] > 0 and len(runner.archive) >= 1
    occupancy = runner.archive.data()["occupancy"]
    assert occupancy.shape[1:] == (16, 56) and np.all(occupancy >= 0)
