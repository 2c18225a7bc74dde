"""An agent kind from an installed package loads inside the simulator actors (not only in the driver)."""

from __future__ import annotations

import os

import numpy as np
import pytest

from dsage_ray import agent_registry
from dsage_ray.config import RunConfig
from dsage_ray.core.evaluation import InProcessEvaluator
from dsage_ray.domains import build_domain
from dsage_ray.ray.pool import SimulatorPool


@pytest.fixture
def config(agent_plugin) -> RunConfig:
    return RunConfig.build({"preset": "tiny", "maze.agent": f"{agent_plugin}:forward", "maze.episodes": 1,
                            "ray.num_workers": 1, "ray.cpus_per_worker": 0.5})


def test_a_plug_in_kind_evaluates_in_the_pool_as_in_process(ray_session, agent_plugin, config):
    # Found through the installed package's metadata, never registered by hand: an actor process
    # knows it only if it reads the entry points itself.
    assert agent_plugin not in agent_registry.REGISTERED
    domain = build_domain(config)
    solutions = domain.random_solutions(6, np.random.default_rng(0))
    seeds = list(range(100, 106))
    expected = InProcessEvaluator(domain=domain)(solutions, seeds)
    with SimulatorPool(config=config) as pool:
        assert all(info["pid"] != os.getpid() for info in pool.actor_info)
        results = pool(solutions, seeds)
    assert not any(result.failed for result in results), [result.error for result in results]
    assert [r.objective for r in results] == [r.objective for r in expected]
    assert all(np.array_equal(a.measures, b.measures) for a, b in zip(results, expected))
