"""surrogate.exact_level_values: values a level fixes by itself replace the network's predictions."""

from __future__ import annotations

import numpy as np
import pytest

from dsage_ray.config import SurrogateConfig
from dsage_ray.domains.mario.domain import MarioDomain
from dsage_ray.domains.mario.encoding import one_hot_levels
from dsage_ray.domains.mario.plugin import MarioConfig
from dsage_ray.domains.mario.tiles import NUM_TILES, sky_tiles
from dsage_ray.domains.maze.domain import MazeDomain
from dsage_ray.domains.maze.plugin import MazeConfig
from dsage_ray.surrogate import Surrogate
from dsage_ray.surrogate.models import encode_solutions
from dsage_ray.surrogate.surrogate import domain_level_values
from tests.surrogate.helpers import random_levels

OCC = (6, 7)


def wall_and_objective(levels: np.ndarray) -> dict[str, np.ndarray]:
    """A toy domain's exact values: channel-1 cells as ``walls``, a constant objective, and an unknown name."""
    return {"walls": levels[:, 1].sum(axis=(1, 2)), "objective": np.full(len(levels), 0.25),
            "not_a_measure": np.zeros(len(levels))}


def make(exact: bool, level_values=wall_and_objective) -> Surrogate:
    config = SurrogateConfig(epochs=1, batch_size=16, device="cpu", precision="fp32", exact_level_values=exact)
    return Surrogate(kind="two_stage", input_channels=5, input_shape=(8, 8), occupancy_shape=OCC, num_measures=2,
                     config=config, seed=0, measure_names=["walls", "path"], level_values=level_values)


def test_exact_values_replace_only_their_own_predictions():
    levels = random_levels(20, size=8, seed=1)
    network = make(False).predict(levels)
    exact = make(True).predict(levels)
    np.testing.assert_array_equal(exact.measures[:, 0], levels[:, 1].sum(axis=(1, 2)))
    np.testing.assert_array_equal(exact.objective, np.full(20, 0.25, np.float32))
    np.testing.assert_array_equal(exact.measures[:, 1], network.measures[:, 1])
    np.testing.assert_array_equal(exact.occupancy, network.occupancy)
    assert not np.array_equal(network.measures[:, 0], exact.measures[:, 0])


def test_the_key_needs_the_domains_values_and_off_ignores_them():
    with pytest.raises(ValueError, match="level_values"):
        make(True, level_values=None)
    with pytest.raises(ValueError, match="computes no measure from the level alone"):
        domain_level_values(object())
    levels = random_levels(5, size=8, seed=2)
    np.testing.assert_array_equal(make(False).predict(levels).measures, make(False, None).predict(levels).measures)


@pytest.mark.parametrize("size", [8, 6])  # 6x6 is padded to 8x8 for the surrogate
def test_maze_values_are_the_wall_count_optimal_path_and_validity_of_each_level(size):
    config = MazeConfig(height=size, width=size, path_channels=True, measures=("num_walls", "optimal_path_length"))
    domain = MazeDomain(config=config)
    solutions = domain.random_solutions(40, np.random.default_rng(0))
    solutions[0] = 1  # all walls: no start, invalid
    solutions[1] = 1
    solutions[1, 3] = 0  # one free cell: invalid
    values = domain.level_values(encode_solutions(domain, solutions))
    levels = [domain.level(s) for s in solutions]
    np.testing.assert_array_equal(values["num_walls"], [level.num_walls for level in levels])
    np.testing.assert_array_equal(values["optimal_path_length"], [level.optimal_path_length for level in levels])
    np.testing.assert_array_equal(values["objective"], [float(level.valid) for level in levels])
    assert values["objective"][:2].tolist() == [0.0, 0.0] and values["objective"].sum() > 10
    assert values["optimal_path_length"].max() > 2
    audit = MazeDomain(config=MazeConfig(height=size, width=size, objective="failure_rate"))
    assert set(audit.level_values(encode_solutions(audit, solutions))) == {"num_walls"}


def test_mario_sky_tiles_come_from_the_one_hot_level():
    domain = MarioDomain(config=MarioConfig())
    rng = np.random.default_rng(0)
    levels = rng.integers(0, NUM_TILES, size=(12, 16, 56))
    levels[:, :, ::3] = 0  # plenty of sky too
    values = domain.level_values(one_hot_levels(levels))
    np.testing.assert_array_equal(values["sky_tiles"], [sky_tiles(level) for level in levels])


@pytest.mark.parametrize("exact", [False, True])
def test_for_domain_wires_the_maze_values_when_the_key_is_on(exact):
    domain = MazeDomain(config=MazeConfig(height=8, width=8))
    config = SurrogateConfig(epochs=1, device="cpu", precision="fp32", exact_level_values=exact)
    surrogate = Surrogate.for_domain(domain, config=config, seed=0)
    encoded = encode_solutions(domain, domain.random_solutions(10, np.random.default_rng(1)))
    walls = surrogate.predict(encoded).measures[:, domain.measure_names.index("num_walls")]
    assert np.array_equal(walls, domain.level_values(encoded)["num_walls"]) == exact


def test_measures_are_exact_only_when_the_level_gives_every_one():
    both = lambda levels: {"walls": levels[:, 1].sum(axis=(1, 2)), "path": levels[:, 2].sum(axis=(1, 2))}  # noqa: E731
    assert make(True, level_values=both).measures_exact
    assert not make(True).measures_exact  # "path" is predicted
    assert not make(False, level_values=both).measures_exact  # the key is off
