"""Paper fidelity of the presets and of Mario's random latents (issue 10, item 6)."""

import numpy as np
import pytest

from dsage_ray.config import RunConfig
from dsage_ray.domains.mario.plugin import MarioConfig


def test_paper_budgets():
    assert RunConfig.build({"domain": "maze", "preset": "paper"}).budget == 100_000
    assert RunConfig.build({"domain": "mario", "preset": "paper"}).budget == 10_000


def test_mario_latent_sigma_per_preset():
    assert RunConfig.build({"domain": "mario", "preset": "paper"}).mario.latent_sigma == 0.2  # the authors'
    # The shipped generator's own prior (benchmarks/bench_latent_sigma.py).
    assert RunConfig.build({"domain": "mario", "preset": "cpu"}).mario.latent_sigma == 1.0
    with pytest.raises(ValueError, match="mario.latent_sigma"):
        RunConfig.build({"domain": "mario", "mario.latent_sigma": 0.0})


@pytest.mark.parametrize("sigma", [0.2, 1.0])
def test_mario_random_latents_follow_latent_sigma(sigma):
    from dsage_ray.domains.mario.domain import MarioDomain

    domain = MarioDomain(config=MarioConfig(latent_sigma=sigma))  # the generator is not needed to sample
    latents = domain.random_solutions(4000, np.random.default_rng(0))
    assert latents.shape == (4000, 32) and latents.dtype == np.float32
    assert latents.std() == pytest.approx(sigma, rel=0.02) and abs(latents.mean()) < 0.02 * sigma


def test_held_out_levels_are_on_in_the_maze_cpu_preset_only():
    assert RunConfig.build({"domain": "maze", "preset": "cpu"}).experimental.holdout_levels == 100
    for domain, preset in (("maze", "paper"), ("maze", "tiny"), ("mario", "tiny")):
        assert RunConfig.build({"domain": domain, "preset": preset}).experimental.holdout_levels == 0
