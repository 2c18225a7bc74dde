"""Small synthetic data for the surrogate tests: a learnable toy task on random one-hot levels."""

from __future__ import annotations

import numpy as np

from dsage_ray.types import EvaluationResult


def random_levels(n: int, *, channels: int = 5, size: int = 8, seed: int = 0) -> np.ndarray:
    """``(n, channels, size, size)`` float32 one-hot levels with random tiles."""
    tiles = np.random.default_rng(seed).integers(0, channels, size=(n, size, size))
    return np.eye(channels, dtype=np.float32)[tiles].transpose(0, 3, 1, 2).copy()


def toy_results(levels: np.ndarray, occupancy_shape: tuple[int, int]) -> list[EvaluationResult]:
    """Targets that are simple functions of the level, so a surrogate can learn them.

    Objective: share of channel-1 ("wall") cells; measures: channel-1 and channel-2 counts / 10;
    occupancy: the channel-0 ("empty") indicator on the occupancy region.
    """
    height, width = occupancy_shape
    results = []
    for level in levels:
        results.append(EvaluationResult(
            objective=float(level[1].mean()),
            measures=np.array([level[1].sum() / 10.0, level[2].sum() / 10.0]),
            occupancy=level[0, :height, :width].astype(np.float32),
        ))
    return results
