import numpy as np
import pytest

from dsage_ray.domains.maze.generator import random_valid_level, random_valid_levels


def test_random_valid_levels_are_valid_and_fixed_per_seed():
    first = random_valid_levels(5, seed=7)
    again = random_valid_levels(5, seed=7)
    other = random_valid_levels(5, seed=8)
    assert all(level.valid for level in first)
    assert [level.walls.tolist() for level in first] == [level.walls.tolist() for level in again]
    assert [level.walls.tolist() for level in first] != [level.walls.tolist() for level in other]


@pytest.mark.parametrize("shape", [(16, 16), (7, 11)])
def test_random_valid_level_respects_shape_and_density(shape):
    rng = np.random.default_rng(0)
    levels = [random_valid_level(rng, height=shape[0], width=shape[1], density_range=(0.0, 0.0))
              for _ in range(3)]
    assert all(level.walls.shape == shape and not level.walls.any() for level in levels)
    dense = [random_valid_level(rng, height=shape[0], width=shape[1], density_range=(0.4, 0.4)) for _ in range(20)]
    assert 0.25 < np.mean([level.walls.mean() for level in dense]) < 0.45
