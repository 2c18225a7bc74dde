import numpy as np
import pytest

from dsage_ray.domains.maze.encoding import CHANNELS, encode_levels
from dsage_ray.domains.maze.level import MazeLevel


def test_one_hot_from_solutions_and_levels_agree():
    rng = np.random.default_rng(0)
    solutions = rng.integers(0, 2, size=(6, 8 * 5)).astype(np.float64)
    encoded = encode_levels(solutions, 8, 5)
    assert encoded.shape == (6, len(CHANNELS), 8, 5) and encoded.dtype == np.float32
    assert (encoded.sum(axis=1) == 1).all()  # exactly one channel per cell
    assert not encoded[:, CHANNELS.index("spare")].any()
    levels = [MazeLevel.from_bitmap(s.reshape(8, 5)) for s in solutions]
    assert np.array_equal(encode_levels(levels, 8, 5), encoded)
    for level, one_hot in zip(levels, encoded):
        assert np.array_equal(one_hot[CHANNELS.index("wall")] > 0, level.walls)
        if level.valid:
            assert one_hot[CHANNELS.index("start")][level.start] == 1
            assert one_hot[CHANNELS.index("goal")][level.goal] == 1
            assert one_hot[CHANNELS.index("start")].sum() == one_hot[CHANNELS.index("goal")].sum() == 1
        else:
            assert not one_hot[CHANNELS.index("start")].any()


def test_wrong_size_rejected():
    with pytest.raises(ValueError, match="expected 4x4"):
        encode_levels([MazeLevel.from_bitmap(np.zeros((3, 3)))], 4, 4)
