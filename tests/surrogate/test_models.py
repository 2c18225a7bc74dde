"""Shapes of the surrogate networks on Maze- and Mario-sized inputs, and input padding."""

import numpy as np
import pytest
import torch

from dsage_ray.surrogate.models import (
    BASE_CHANNELS,
    BASE_DILATIONS,
    MeasurePredictor,
    OccupancyPredictor,
    OneStageModel,
    ResidualBlock,
    TwoStageModel,
    pad_to_power_of_two,
)

MAZE = dict(input_channels=5, input_size=16, occupancy_shape=(16, 16))
MARIO = dict(input_channels=17, input_size=64, occupancy_shape=(16, 56))


@pytest.mark.parametrize("domain", [MAZE, MARIO], ids=["maze", "mario"])
def test_two_stage_shapes(domain):
    model = TwoStageModel(**domain, num_measures=2).eval()
    x = torch.zeros(3, domain["input_channels"], domain["input_size"], domain["input_size"])
    with torch.inference_mode():
        out = model(x)
    assert out.objective.shape == (3,)
    assert out.measures.shape == (3, 2)
    assert out.occupancy.shape == (3, *domain["occupancy_shape"])


@pytest.mark.parametrize("domain", [MAZE, MARIO], ids=["maze", "mario"])
def test_one_stage_shapes(domain):
    model = OneStageModel(input_channels=domain["input_channels"], input_size=domain["input_size"],
                          num_measures=3).eval()
    with torch.inference_mode():
        out = model(torch.zeros(2, domain["input_channels"], domain["input_size"], domain["input_size"]))
    assert out.objective.shape == (2,)
    assert out.measures.shape == (2, 3)
    assert out.occupancy is None


@pytest.mark.parametrize("size, convs", [(8, 1), (16, 2), (64, 4)])
def test_measure_predictor_downsamples_to_4x4(size, convs):
    model = MeasurePredictor(input_channels=6, input_size=size, num_measures=2)
    layers = [m for m in model.features if isinstance(m, torch.nn.Conv2d)]
    assert len(layers) == convs
    assert model.heads.in_features == layers[-1].out_channels * 16
    assert model.heads.out_features == 3


@pytest.mark.parametrize("size", [4, 12, 24])
def test_rejects_sizes_that_are_not_powers_of_two(size):
    with pytest.raises(ValueError, match="power of two"):
        MeasurePredictor(input_channels=5, input_size=size, num_measures=2)


def test_rejects_occupancy_larger_than_input():
    with pytest.raises(ValueError, match="does not fit"):
        TwoStageModel(input_channels=5, input_size=16, occupancy_shape=(16, 17), num_measures=2)


def test_occupancy_is_the_top_left_of_the_input_grid():
    model = TwoStageModel(input_channels=17, input_size=64, occupancy_shape=(16, 56), num_measures=2).eval()
    x = torch.rand(2, 17, 64, 64)
    with torch.inference_mode():
        full = model.occupancy_predictor(x)
        assert torch.equal(model(x).occupancy, full[:, :16, :56])


def test_pad_to_power_of_two_keeps_level_top_left_and_marks_padding():
    levels = np.eye(5, dtype=np.float32)[np.random.default_rng(0).integers(0, 5, (2, 10, 12))].transpose(0, 3, 1, 2)
    padded = pad_to_power_of_two(levels, pad_channel=1)
    assert padded.shape == (2, 5, 16, 16) and padded.dtype == np.float32
    assert np.array_equal(padded[:, :, :10, :12], levels)
    assert np.all(padded[:, 1, 10:, :] == 1) and np.all(padded[:, 1, :, 12:] == 1)
    assert np.all(padded.sum(axis=1) == 1)  # still one-hot everywhere


def test_pad_to_power_of_two_sizes():
    assert pad_to_power_of_two(np.zeros((1, 17, 16, 56))).shape == (1, 17, 64, 64)
    assert pad_to_power_of_two(np.zeros((1, 5, 3, 3))).shape == (1, 5, 8, 8)
    same = np.zeros((1, 5, 16, 16), dtype=np.float32)
    assert pad_to_power_of_two(same) is same
    with pytest.raises(ValueError):
        pad_to_power_of_two(same, pad_channel=5)


def _receptive_field(model: torch.nn.Module, size: int = 32) -> int:
    """Width of the input square that moves the centre cell's output (eval mode, so BatchNorm is per cell)."""
    x = torch.zeros(1, 5, size, size, requires_grad=True)
    model.eval()(x)[0, size // 2, size // 2].backward()
    cols = torch.nonzero(x.grad.abs().sum(dim=(0, 1, 2)))
    return int(cols.max() - cols.min() + 1)


@pytest.mark.parametrize("dilations, field", [((1, 1), 11), ((1, 2, 4), 31), ((), 3)])
def test_occupancy_receptive_field_is_3_plus_4_times_the_dilations(dilations, field):
    torch.manual_seed(0)
    model = OccupancyPredictor(input_channels=5, hidden_channels=8, dilations=dilations)
    assert _receptive_field(model) == field


def test_width_and_blocks_are_configurable_and_default_to_the_paper():
    paper = TwoStageModel(**MAZE, num_measures=2)
    assert paper.occupancy_predictor.net[0].out_channels == BASE_CHANNELS == 64
    assert sum(isinstance(m, ResidualBlock) for m in paper.modules()) == len(BASE_DILATIONS) == 2
    small = TwoStageModel(**MAZE, num_measures=2, channels=16, dilations=(1, 2, 4))
    blocks = [m for m in small.modules() if isinstance(m, ResidualBlock)]
    assert [b.conv1.dilation for b in blocks] == [(1, 1), (2, 2), (4, 4)]
    assert small.measure_predictor.features[0].out_channels == 16
    assert OneStageModel(input_channels=5, input_size=16, num_measures=2, channels=8).measure_predictor.heads.in_features == 16 * 16
    with torch.inference_mode():
        out = small.eval()(torch.zeros(2, 5, 16, 16))
    assert out.occupancy.shape == (2, 16, 16)
    with pytest.raises(ValueError, match="dilation"):
        ResidualBlock(channels=4, dilation=0)


def test_a_model_with_level_statistics_feeds_them_to_its_heads_and_needs_them():
    from dsage_ray.domains.maze.encoding import EMPTY, GOAL, START
    from dsage_ray.surrogate.grid_features import DistanceFields, LevelStatistics
    from dsage_ray.surrogate.models import MeasurePredictor, TwoStageModel

    fields = DistanceFields(free_channels=(EMPTY, START, GOAL), start_channel=START, goal_channel=GOAL, norm=32)
    statistics = LevelStatistics(fields=fields, norm=32)
    torch.manual_seed(0)
    model = TwoStageModel(input_channels=5, input_size=8, occupancy_shape=(8, 8), num_measures=2, channels=8,
                          statistics=statistics)
    levels = torch.zeros(4, 5, 8, 8)
    levels[:, EMPTY] = 1
    levels[:, EMPTY, 0, 0], levels[:, START, 0, 0] = 0, 1
    levels[:, EMPTY, 7, 7], levels[:, GOAL, 7, 7] = 0, 1
    levels[1:, EMPTY, 3, :6], levels[1:, 1, 3, :6] = 0, 1  # a wall across three of them
    out = model(levels)
    assert out.measures.shape == (4, 2) and out.objective.shape == (4,)
    out.measures.sum().backward()
    assert model.measure_predictor.scalar_branch[1].weight.grad.abs().sum() > 0
    # The statistics differ with the wall, and so does the prediction.
    assert not torch.allclose(out.measures[0], out.measures[1])
    predictor = MeasurePredictor(input_channels=6, input_size=8, num_measures=2, num_scalars=LevelStatistics.size)
    with pytest.raises(ValueError, match="scalars"):
        predictor(torch.zeros(2, 6, 8, 8))
