"""The DSAGE surrogate networks (SPEC: the surrogate, paper appendix "Deep Surrogate Model").

Inputs are one-hot levels ``(n, channels, size, size)`` with ``size`` a power of two ≥ 8, so that the
measure predictor's stride-2 convolutions reach exactly 4×4. Domains whose levels are not such a
square (Mario's 16×56, a 10×12 maze) are padded by the caller with :func:`pad_to_power_of_two`; the
level then sits in the top-left corner, which is where the occupancy grid is read back from.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, NamedTuple

import numpy as np
import torch
from torch import nn
from torch.nn import functional as F

if TYPE_CHECKING:
    from dsage_ray.surrogate.grid_features import LevelStatistics
    from dsage_ray.types import Domain, Solutions

#: Negative slope of every LeakyReLU in the surrogate (the paper's value).
LEAKY_SLOPE = 0.2
#: Channels of the first convolution of both predictors (the paper's; ``surrogate.channels``).
BASE_CHANNELS = 64
#: Dilation of each residual block of the occupancy predictor: two plain blocks (the paper's; wider receptive
#: fields did not predict better, docs/results/surrogate_accuracy).
BASE_DILATIONS = (1, 1)
#: The measure predictor downsamples until this spatial size, then flattens.
FINAL_SIZE = 4
#: Width of the MLP that feeds per-level scalars (:class:`~dsage_ray.surrogate.grid_features.LevelStatistics`) to
#: the measure heads.
SCALAR_WIDTH = 64


class ModelOutput(NamedTuple):
    """What a surrogate network predicts for a batch of ``n`` levels.

    Attributes:
        objective: Shape ``(n,)``.
        measures: Shape ``(n, num_measures)``.
        occupancy: Shape ``(n, H, W)`` (the domain's occupancy shape), or ``None`` for a one-stage model.
    """

    objective: torch.Tensor
    measures: torch.Tensor
    occupancy: torch.Tensor | None


def pad_to_power_of_two(encoded: np.ndarray, pad_channel: int = 0) -> np.ndarray:
    """Pads one-hot levels to the smallest square power-of-two grid (at least 8×8) that holds them.

    The level keeps its top-left corner; each padding cell is one-hot in ``pad_channel`` (Mario pads
    with channel 0, the empty tile, as its GAN was trained).

    Args:
        encoded: One-hot levels, shape ``(n, channels, height, width)``.
        pad_channel: The channel set to 1 on padding cells.

    Returns:
        float32 array of shape ``(n, channels, size, size)``; ``encoded`` itself (as float32) when it
        already has that shape.
    """
    n, channels, height, width = encoded.shape
    if (height, width) == (1, 1):  # a parameter vector (the gym domain's levels), read by an MLP: no grid to pad
        return np.asarray(encoded, dtype=np.float32)
    if not 0 <= pad_channel < channels:
        raise ValueError(f"pad_channel {pad_channel} is not one of the {channels} channels")
    size = max(8, 1 << (max(height, width) - 1).bit_length())
    encoded = np.asarray(encoded, dtype=np.float32)
    if (height, width) == (size, size):
        return encoded
    padded = np.zeros((n, channels, size, size), dtype=np.float32)
    padded[:, pad_channel] = 1.0
    padded[:, :, :height, :width] = encoded
    return padded


def encode_solutions(domain: "Domain", solutions: "Solutions") -> np.ndarray:
    """The surrogate's input for ``solutions``: the domain's one-hot levels, padded to a square power of two."""
    return pad_to_power_of_two(domain.encode(solutions), pad_channel=domain.encoding_pad_channel)


def _check_input_size(input_size: int) -> None:
    if input_size < 8 or input_size & (input_size - 1):
        raise ValueError(f"input size must be a power of two >= 8 (pad with pad_to_power_of_two), got {input_size}")


class ResidualBlock(nn.Module):
    """conv3×3–BN–ReLU–conv3×3–BN, plus the identity, then ReLU (He et al., 2016).

    With ``dilation`` d both convolutions read cells d apart (zero padding d keeps the size): the
    block widens the receptive field by 4·d cells at the cost of a plain block.
    """

    def __init__(self, *, channels: int, dilation: int = 1) -> None:
        super().__init__()
        if dilation < 1:
            raise ValueError(f"dilation must be >= 1, got {dilation}")
        # No conv biases: the BatchNorm right after each conv has its own shift.
        self.conv1 = nn.Conv2d(channels, channels, kernel_size=3, padding=dilation, dilation=dilation, bias=False)
        self.bn1 = nn.BatchNorm2d(channels)
        self.conv2 = nn.Conv2d(channels, channels, kernel_size=3, padding=dilation, dilation=dilation, bias=False)
        self.bn2 = nn.BatchNorm2d(channels)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        out = F.relu(self.bn1(self.conv1(x)))
        out = self.bn2(self.conv2(out))
        return F.relu(out + x)


class OccupancyPredictor(nn.Module):
    """Predicts the occupancy grid (expected agent visits per cell) on the input grid.

    Conv3×3(→64) + LeakyReLU(0.2), two residual blocks, Conv1×1(→1) in the paper; ``hidden_channels``
    and ``dilations`` (one residual block per entry) change the width and the blocks. Every layer keeps
    the spatial size, so the output is aligned cell-for-cell with the input level. The receptive field
    is ``3 + 4·sum(dilations)`` cells wide (11 in the paper; ``(1, 2, 4)`` gives 31, a whole 16×16 maze).
    """

    def __init__(self, *, input_channels: int, hidden_channels: int = BASE_CHANNELS,
                 dilations: tuple[int, ...] = BASE_DILATIONS) -> None:
        super().__init__()
        self.net = nn.Sequential(
            nn.Conv2d(input_channels, hidden_channels, kernel_size=3, padding=1),
            nn.LeakyReLU(LEAKY_SLOPE),
            *(ResidualBlock(channels=hidden_channels, dilation=d) for d in dilations),
            nn.Conv2d(hidden_channels, 1, kernel_size=1),
        )

    def forward(self, levels: torch.Tensor, *, bf16_blocks: bool = False) -> torch.Tensor:
        """Maps ``(n, C, S, S)`` levels to ``(n, S, S)`` float32 occupancy.

        ``bf16_blocks`` runs the residual blocks, most of the two-stage model's arithmetic, under bf16
        autocast (inference only). The first convolution stays float32 because it reads the one-hot level,
        where each output sums only 9 weights, so their bf16 rounding does not average out; the last stays
        float32 because it writes the output.
        """
        stem, blocks, head = self.net[:2], self.net[2:-1], self.net[-1]
        features = stem(levels)
        if bf16_blocks:
            # Cast once up front: with a float32 input every residual sum would promote back to float32 and
            # each convolution would convert again (measured 1.5x slower, same agreement with float32).
            with torch.autocast(levels.device.type, dtype=torch.bfloat16):
                features = blocks(features.bfloat16()).float()
        else:
            features = blocks(features)
        return head(features).squeeze(1)


class MeasurePredictor(nn.Module):
    """Predicts the objective and the measures from a (possibly occupancy-augmented) level.

    Conv4×4 stride 2 (→64, ``base_channels``) + LeakyReLU(0.2), then Conv4×4 stride 2 doubling the
    channels, each with BatchNorm + LeakyReLU, until the grid is 4×4; flatten; one linear head per output.
    With ``num_scalars`` > 0 (not in the paper) the heads also read per-level scalars
    (:class:`~dsage_ray.surrogate.grid_features.LevelStatistics`) through a small MLP, BatchNorm first since their scales differ.
    """

    def __init__(self, *, input_channels: int, input_size: int, num_measures: int,
                 base_channels: int = BASE_CHANNELS, num_scalars: int = 0) -> None:
        super().__init__()
        _check_input_size(input_size)
        layers: list[nn.Module] = [
            nn.Conv2d(input_channels, base_channels, kernel_size=4, stride=2, padding=1),
            nn.LeakyReLU(LEAKY_SLOPE),
        ]
        channels, size = base_channels, input_size // 2
        while size > FINAL_SIZE:
            layers += [
                nn.Conv2d(channels, 2 * channels, kernel_size=4, stride=2, padding=1, bias=False),
                nn.BatchNorm2d(2 * channels),
                nn.LeakyReLU(LEAKY_SLOPE),
            ]
            channels, size = 2 * channels, size // 2
        layers.append(nn.Flatten())
        self.features = nn.Sequential(*layers)
        self.scalar_branch = None
        if num_scalars > 0:
            self.scalar_branch = nn.Sequential(
                nn.BatchNorm1d(num_scalars), nn.Linear(num_scalars, SCALAR_WIDTH), nn.LeakyReLU(LEAKY_SLOPE),
                nn.Linear(SCALAR_WIDTH, SCALAR_WIDTH), nn.LeakyReLU(LEAKY_SLOPE))
        # Row i of this weight is head i (objective, then each measure): the same parameters and
        # initialisation as 1 + num_measures separate nn.Linear(features, 1), in one matmul.
        width = channels * FINAL_SIZE * FINAL_SIZE + (SCALAR_WIDTH if num_scalars > 0 else 0)
        self.heads = nn.Linear(width, 1 + num_measures)

    def forward(self, x: torch.Tensor, scalars: torch.Tensor | None = None) -> tuple[torch.Tensor, torch.Tensor]:
        """Returns objective ``(n,)`` and measures ``(n, num_measures)``; ``scalars`` ``(n, num_scalars)``."""
        features = self.features(x)
        if self.scalar_branch is not None:
            if scalars is None:
                raise ValueError("this measure predictor reads per-level scalars; none were given")
            features = torch.cat([features, self.scalar_branch(scalars)], dim=1)
        out = self.heads(features)
        return out[:, 0], out[:, 1:]


class TwoStageModel(nn.Module):
    """DSAGE's model: predicted occupancy, stacked with the level, feeds the measure predictor.

    Args:
        input_channels: Channels of the one-hot level.
        input_size: Side of the (square, power-of-two) input grid.
        occupancy_shape: ``(H, W)`` of the domain's occupancy grid, read from the top-left of the input grid.
        num_measures: Number of measure heads.
        channels: Width of both predictors (:data:`BASE_CHANNELS`, the paper's 64).
        dilations: The occupancy predictor's residual blocks (:class:`OccupancyPredictor`).
        statistics: Per-level scalars computed from the level and fed to the measure heads (not in the
            paper); ``None``: the paper's model.
    """

    def __init__(self, *, input_channels: int, input_size: int, occupancy_shape: tuple[int, int],
                 num_measures: int, channels: int = BASE_CHANNELS,
                 dilations: tuple[int, ...] = BASE_DILATIONS, statistics: "LevelStatistics | None" = None) -> None:
        super().__init__()
        _check_input_size(input_size)
        height, width = occupancy_shape
        if not (0 < height <= input_size and 0 < width <= input_size):
            raise ValueError(f"occupancy shape {occupancy_shape} does not fit the {input_size}x{input_size} input")
        self.occupancy_shape = (height, width)
        self.input_size = input_size
        self.occupancy_predictor = OccupancyPredictor(input_channels=input_channels, hidden_channels=channels,
                                                      dilations=tuple(dilations))
        self.statistics = statistics
        self.measure_predictor = MeasurePredictor(input_channels=input_channels + 1, input_size=input_size,
                                                  num_measures=num_measures, base_channels=channels,
                                                  num_scalars=statistics.size if statistics is not None else 0)

    def forward(self, levels: torch.Tensor, *, bf16_blocks: bool = False) -> ModelOutput:
        """``bf16_blocks``: see :meth:`OccupancyPredictor.forward`; the measure predictor is float32 always."""
        height, width = self.occupancy_shape
        occupancy = self.occupancy_predictor(levels, bf16_blocks=bf16_blocks)[:, :height, :width]
        # The measure predictor sees exactly the supervised occupancy, with zeros on the padding
        # (whose predictions are never trained and would only add noise).
        full = F.pad(occupancy, (0, self.input_size - width, 0, self.input_size - height))
        scalars = self.statistics(levels) if self.statistics is not None else None
        objective, measures = self.measure_predictor(torch.cat([levels, full.unsqueeze(1)], dim=1), scalars)
        return ModelOutput(objective, measures, occupancy)


class OneStageModel(nn.Module):
    """The ablation without ancillary data: the measure predictor on the one-hot level alone."""

    def __init__(self, *, input_channels: int, input_size: int, num_measures: int,
                 channels: int = BASE_CHANNELS, statistics: "LevelStatistics | None" = None) -> None:
        super().__init__()
        self.statistics = statistics
        self.measure_predictor = MeasurePredictor(input_channels=input_channels, input_size=input_size,
                                                  num_measures=num_measures, base_channels=channels,
                                                  num_scalars=statistics.size if statistics is not None else 0)

    def forward(self, levels: torch.Tensor, *, bf16_blocks: bool = False) -> ModelOutput:
        """``bf16_blocks`` is accepted for a uniform interface; this model has no residual blocks."""
        scalars = self.statistics(levels) if self.statistics is not None else None
        objective, measures = self.measure_predictor(levels, scalars)
        return ModelOutput(objective, measures, None)


def _mlp(inputs: int, width: int, outputs: int) -> nn.Sequential:
    return nn.Sequential(nn.Linear(inputs, width), nn.LeakyReLU(LEAKY_SLOPE), nn.Linear(width, width),
                         nn.LeakyReLU(LEAKY_SLOPE), nn.Linear(width, outputs))


class VectorTwoStageModel(nn.Module):
    """The two-stage model for levels that are parameter vectors ``(n, P, 1, 1)`` (the gym domain): one MLP predicts
    the occupancy histogram ``(H, W)`` from the parameters, a second the objective and measures from the parameters
    and that histogram.

    Args:
        input_channels: Parameters per level.
        occupancy_shape: ``(H, W)`` of the histogram.
        num_measures: Number of measure heads.
        width: Hidden units of each MLP (``surrogate.channels``).
    """

    def __init__(self, *, input_channels: int, occupancy_shape: tuple[int, int], num_measures: int,
                 width: int = BASE_CHANNELS) -> None:
        super().__init__()
        self.occupancy_shape = tuple(occupancy_shape)
        cells = int(np.prod(self.occupancy_shape))
        self.occupancy_predictor = _mlp(input_channels, width, cells)
        self.measure_predictor = _mlp(input_channels + cells, width, 1 + num_measures)

    def forward(self, levels: torch.Tensor, *, bf16_blocks: bool = False) -> ModelOutput:
        """``bf16_blocks`` is accepted for a uniform interface; these MLPs run in float32."""
        parameters = levels.flatten(1)
        occupancy = self.occupancy_predictor(parameters)
        out = self.measure_predictor(torch.cat([parameters, occupancy], dim=1))
        return ModelOutput(out[:, 0], out[:, 1:], occupancy.reshape(-1, *self.occupancy_shape))


class VectorOneStageModel(nn.Module):
    """The one-stage ablation for parameter vectors: one MLP from the parameters to the objective and measures."""

    def __init__(self, *, input_channels: int, num_measures: int, width: int = BASE_CHANNELS) -> None:
        super().__init__()
        self.measure_predictor = _mlp(input_channels, width, 1 + num_measures)

    def forward(self, levels: torch.Tensor, *, bf16_blocks: bool = False) -> ModelOutput:
        out = self.measure_predictor(levels.flatten(1))
        return ModelOutput(out[:, 0], out[:, 1:], None)


class WithInputFields(nn.Module):
    """A surrogate network that reads its level plus parameter-free input fields
    (:mod:`dsage_ray.surrogate.grid_features`: ``DistanceFields``, ``RandomWalkFields``), appended in order; build
    ``model`` with their ``fields`` more input channels. Same outputs and ``bf16_blocks`` argument as the wrapped
    model."""

    def __init__(self, inputs: "list[nn.Module] | tuple[nn.Module, ...]", model: nn.Module) -> None:
        super().__init__()
        self.inputs = nn.ModuleList(inputs)
        self.model = model

    def forward(self, levels: torch.Tensor, *, bf16_blocks: bool = False) -> ModelOutput:
        channels = levels.shape[1]
        extended = levels
        for module in self.inputs:
            extended = torch.cat([extended, module(levels)[:, channels:]], dim=1)
        return self.model(extended, bf16_blocks=bf16_blocks)
