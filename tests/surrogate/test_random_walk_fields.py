"""grid_features.RandomWalkFields: a uniform random walker's expected visits before it finds the goal."""

from __future__ import annotations

import numpy as np
import torch

from dsage_ray.domains.maze.encoding import EMPTY, GOAL, SPARE, START, WALL, encode_levels
from dsage_ray.domains.maze.generator import random_valid_levels
from dsage_ray.surrogate import pad_to_power_of_two
from dsage_ray.surrogate.grid_features import DistanceFields, RandomWalkFields
from dsage_ray.surrogate.models import WithInputFields


def walker(norm: float = 1.0) -> RandomWalkFields:
    return RandomWalkFields(free_channels=(EMPTY, START, GOAL), start_channel=START, goal_channel=GOAL, norm=norm)


def encode(walls: np.ndarray) -> torch.Tensor:
    n, height, width = walls.shape
    return torch.from_numpy(pad_to_power_of_two(encode_levels(walls.reshape(n, -1).astype(np.int8), height, width),
                                                SPARE))


def test_a_corridor_takes_the_square_of_its_length_and_visits_the_start_end_most():
    walls = np.ones((1, 8, 8), dtype=bool)
    walls[0, 3, :] = False  # one corridor of 8 cells: start and goal at its two ends, 7 steps apart
    visits = walker().visits(encode(walls))[0].numpy()
    assert np.isclose(visits.sum(), 49.0)  # the hitting time along a path is its length squared
    row = visits[3, :8]
    # Expected visits fall linearly towards the goal (2·(7 − k) on inner cells, 7 on the reflecting end).
    np.testing.assert_allclose(row, [7, 12, 10, 8, 6, 4, 2, 0], atol=1e-9)
    assert (np.delete(visits, 3, axis=0) == 0).all()


def test_cells_the_walker_cannot_reach_and_levels_without_a_start_get_no_visits():
    walls = np.ones((2, 8, 8), dtype=bool)
    walls[0, 3, :] = False
    walls[0, 6, 1:4] = False  # a pocket the walker cannot reach: its own Laplacian block would be singular
    walls[1] = True  # no free cell, no start
    encoded = encode(walls)
    encoded[1] = 0
    encoded[1, WALL] = 1  # every cell a wall
    visits = walker().visits(encoded).numpy()
    assert np.isclose(visits[0].sum(), 49.0) and (visits[0, 6] == 0).all()
    assert (visits[1] == 0).all()


def test_hitting_times_match_a_monte_carlo_walker():
    mazes = random_valid_levels(3, seed=4, height=6, width=6, density_range=(0.2, 0.4))
    walls = np.stack([m.walls for m in mazes]).astype(bool)
    hitting = walker().visits(encode(walls)).sum(dim=(1, 2)).numpy()
    rng = np.random.default_rng(0)
    for maze, expected in zip(mazes, hitting):
        steps = []
        for _ in range(2000):
            cell, count = maze.start, 0
            while cell != maze.goal:
                r, c = cell
                options = [(r + dr, c + dc) for dr, dc in ((1, 0), (-1, 0), (0, 1), (0, -1))
                           if 0 <= r + dr < 6 and 0 <= c + dc < 6 and not maze.walls[r + dr, c + dc]]
                cell = options[rng.integers(len(options))]
                count += 1
            steps.append(count)
        assert abs(np.mean(steps) - expected) < 4 * np.std(steps) / np.sqrt(len(steps)) + 1e-9


def test_the_channel_is_the_scaled_log_of_the_visits_and_the_wrapper_appends_every_field():
    mazes = random_valid_levels(5, seed=2, height=10, width=12, density_range=(0.0, 0.5))
    encoded = encode(np.stack([m.walls for m in mazes]).astype(bool)).float()
    walk = walker(norm=3.0)
    out = walk(encoded)
    assert out.shape == (5, 6, 16, 16)
    np.testing.assert_allclose(out[:, 5].numpy(), (torch.log1p(walk.visits(encoded)) / 3.0).float().numpy(),
                               rtol=1e-6)
    seen = []
    inner = torch.nn.Module()
    inner.forward = lambda levels, bf16_blocks=False: seen.append(levels) or levels  # type: ignore[method-assign]
    fields = DistanceFields(free_channels=(EMPTY, START, GOAL), start_channel=START, goal_channel=GOAL, norm=1.0)
    WithInputFields([fields, walk], inner)(encoded)
    assert seen[0].shape == (5, 5 + DistanceFields.fields + RandomWalkFields.fields, 16, 16)
    np.testing.assert_allclose(seen[0][:, :8].numpy(), fields(encoded).numpy())
    np.testing.assert_allclose(seen[0][:, 8].numpy(), out[:, 5].numpy())
