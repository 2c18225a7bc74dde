"""surrogate.prior_measure: a domain's parameter-free prior blended into one measure's prediction."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from dsage_ray.config import ConfigError, RunConfig, SurrogateConfig
from dsage_ray.surrogate import Surrogate
from dsage_ray.surrogate.surrogate import PRIOR_WEIGHT, domain_prior
from dsage_ray.types import EvaluationResult
from tests.surrogate.helpers import random_levels

OCC = (6, 7)


def wall_count(levels: torch.Tensor) -> torch.Tensor:
    """A toy prior: the channel-1 cells of each level."""
    return levels[:, 1].sum(dim=(1, 2)).double()


def make(prior=wall_count, **config) -> Surrogate:
    config = SurrogateConfig(**{"epochs": 1, "batch_size": 16, "device": "cpu", "precision": "fp32",
                                "prior_measure": "path", **config})
    return Surrogate(kind="two_stage", input_channels=5, input_shape=(8, 8), occupancy_shape=OCC, num_measures=2,
                     config=config, seed=0, measure_names=["walls", "path"], prior=prior)


def dataset_where_the_path_is_a_line_in_the_log_prior(surrogate, n=48):
    levels = random_levels(n, size=8, seed=3)
    walls = levels[:, 1].sum(axis=(1, 2))
    path = 40.0 + 25.0 * np.log1p(walls)
    dataset = surrogate.make_dataset()
    dataset.append(encoded=levels, results=[
        EvaluationResult(objective=1.0, measures=np.array([w / 10.0, p]), occupancy=np.zeros(OCC, np.float32))
        for w, p in zip(walls, path)])
    return dataset, levels, path


def test_training_fits_the_prior_and_prediction_blends_it_into_that_measure_only():
    surrogate = make()
    dataset, levels, path = dataset_where_the_path_is_a_line_in_the_log_prior(surrogate)
    before = surrogate.predict(levels)  # no fit yet: the network alone
    plain = make(prior=None, prior_measure="")
    np.testing.assert_allclose(before.measures, plain.predict(levels).measures)
    surrogate.train(dataset)
    intercept, slope = surrogate.state_dict()["prior_fit"]
    assert intercept == pytest.approx(40.0) and slope == pytest.approx(25.0)
    surrogate.model.eval()
    with torch.inference_mode():
        network = surrogate._sum_occupancy(surrogate.model(torch.from_numpy(levels))).measures.numpy()
    blended = surrogate.predict(levels)
    np.testing.assert_allclose(blended.measures[:, 1], PRIOR_WEIGHT * path + (1 - PRIOR_WEIGHT) * network[:, 1],
                               rtol=1e-5, atol=1e-3)
    np.testing.assert_allclose(blended.measures[:, 0], network[:, 0], rtol=1e-6)


def test_the_fit_is_saved_and_restored_and_an_older_checkpoint_starts_without_one():
    surrogate = make()
    dataset, levels, _ = dataset_where_the_path_is_a_line_in_the_log_prior(surrogate)
    surrogate.train(dataset)
    state = surrogate.state_dict()
    restored = make()
    restored.load_state_dict(state)
    np.testing.assert_array_equal(restored.predict(levels).measures, surrogate.predict(levels).measures)
    old = {key: value for key, value in state.items() if key != "prior_fit"}
    restored.load_state_dict(old)
    assert restored.state_dict()["prior_fit"] is None


def test_a_prior_measure_needs_a_prior_and_a_measure_of_that_name():
    with pytest.raises(ValueError, match="needs the domain's prior"):
        make(prior=None)
    with pytest.raises(ValueError, match="not one of the measures"):
        make(prior_measure="length")
    with pytest.raises(ConfigError, match="surrogate.prior_measure"):
        RunConfig.build({"domain": "maze", "surrogate.prior_measure": "steps"})


def test_the_maze_domain_has_the_walkers_prior_for_the_path_length_only():
    from dsage_ray.domains import build_domain
    from dsage_ray.domains.maze.generator import random_valid_levels
    from dsage_ray.surrogate.models import encode_solutions

    config = RunConfig.build({"domain": "maze", "maze.agent": "builtin:wall_follower",
                              "surrogate.prior_measure": "mean_path_length"})
    domain = build_domain(config)
    prior = domain_prior(domain, "mean_path_length")
    mazes = random_valid_levels(3, seed=1, height=16, width=16, density_range=(0.2, 0.4))
    solutions = np.stack([m.walls.reshape(-1) for m in mazes]).astype(np.float64)
    hitting = prior(torch.from_numpy(encode_solutions(domain, solutions))).numpy()
    optimal = np.array([m.optimal_path_length for m in mazes])
    assert hitting.shape == (3,) and np.all(hitting >= optimal)
    assert domain_prior(domain, "") is None
    with pytest.raises(ValueError, match="no prior for it"):
        domain_prior(domain, "num_walls")
    with pytest.raises(ValueError, match="no prior for it"):
        domain_prior(object(), "mean_path_length")
