"""grid_features.DistanceFields: BFS distance channels of one-hot Maze levels, checked against the domain's BFS."""

from __future__ import annotations

import numpy as np
import torch

from dsage_ray.domains.maze.encoding import EMPTY, GOAL, SPARE, START, encode_levels
from dsage_ray.domains.maze.generator import random_valid_levels
from dsage_ray.domains.maze.level import path_distances
from dsage_ray.surrogate import Surrogate, pad_to_power_of_two
from dsage_ray.surrogate.grid_features import DistanceFields
from dsage_ray.surrogate.models import WithInputFields
from dsage_ray.config import SurrogateConfig


def levels(n: int = 12, seed: int = 0):
    return random_valid_levels(n, seed=seed, height=10, width=12, density_range=(0.0, 0.6))


def test_fields_are_the_distances_from_the_start_to_the_goal_and_the_detour():
    mazes = levels()
    walls = np.stack([m.walls.reshape(-1) for m in mazes]).astype(np.int8)
    encoded = torch.from_numpy(pad_to_power_of_two(encode_levels(walls, 10, 12), SPARE))
    fields = DistanceFields(free_channels=(EMPTY, START, GOAL), start_channel=START, goal_channel=GOAL, norm=2.0)
    out = fields(encoded).numpy()
    assert out.shape == (12, 8, 16, 16)
    np.testing.assert_array_equal(out[:, :5], encoded.numpy())
    for maze, row in zip(mazes, out):
        from_start, to_goal = path_distances(maze.walls, maze.start), path_distances(maze.walls, maze.goal)
        reach = np.isfinite(from_start)
        np.testing.assert_allclose(row[5, :10, :12][reach], from_start[reach] / 2)
        np.testing.assert_allclose(row[6, :10, :12][reach], to_goal[reach] / 2)
        detour = from_start + to_goal - maze.optimal_path_length
        np.testing.assert_allclose(row[7, :10, :12][reach], detour[reach] / 2)
        assert (row[5:, :10, :12][:, ~reach] == 0).all() and (row[5:, 10:] == 0).all() and (row[5:, :, 12:] == 0).all()


def test_a_wrapped_two_stage_surrogate_trains_and_keeps_its_occupancy_head():
    mazes = levels(8, seed=1)
    walls = np.stack([m.walls.reshape(-1) for m in mazes]).astype(np.int8)
    encoded = pad_to_power_of_two(encode_levels(walls, 10, 12), SPARE)
    config = SurrogateConfig(device="cpu", epochs=1, batch_size=4)
    surrogate = Surrogate(kind="two_stage", input_channels=5 + DistanceFields.fields, input_shape=(16, 16),
                          occupancy_shape=(10, 12), num_measures=1, config=config, seed=0)
    fields = DistanceFields(free_channels=(EMPTY, START, GOAL), start_channel=START, goal_channel=GOAL, norm=60)
    surrogate.model = WithInputFields([fields], surrogate.model)
    surrogate.input_channels = 5
    surrogate.optimizer = torch.optim.Adam(surrogate.model.parameters())
    assert surrogate.head_names[-1] == "occupancy"
    from dsage_ray.types import EvaluationResult

    dataset = surrogate.make_dataset()
    dataset.append(encoded=encoded, results=[EvaluationResult(objective=1.0, measures=np.array([float(i)]),
                                                              occupancy=np.zeros((10, 12), np.float32))
                                             for i in range(8)])
    losses = surrogate.train(dataset)
    assert np.isfinite(losses["total"])
    assert surrogate.predict(encoded).occupancy.shape == (8, 10, 12)
