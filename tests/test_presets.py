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


def test_no_preset_holds_levels_out_and_the_maze_cpu_preset_is_the_screened_design():
    for domain, preset in (("maze", "paper"), ("maze", "cpu"), ("maze", "tiny"), ("mario", "tiny")):
        assert RunConfig.build({"domain": domain, "preset": preset}).experimental.holdout_levels == 0
    cpu = RunConfig.build({"domain": "maze", "preset": "cpu"})
    assert (cpu.surrogate.channels, cpu.selection.block) == (16, (2, 3))
    assert cpu.selection.screen_episodes == 1 and cpu.selection.screen_gain
    # The baselines stay the paper's: unscreened.
    for variant in ("map_elites", "dr"):
        baseline = RunConfig.build({"domain": "maze", "preset": "cpu", "variant": variant})
        assert baseline.selection.screen_episodes == 0 and not baseline.selection.screen_gain
