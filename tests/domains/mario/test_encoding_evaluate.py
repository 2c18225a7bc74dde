"""One-hot encoding and the occupancy / measure bookkeeping (no Java needed)."""

from __future__ import annotations

import numpy as np
import pytest

from dsage_ray.domains.mario.encoding import one_hot_levels
from dsage_ray.domains.mario.evaluate import occupancy_grid
from dsage_ray.domains.mario.render import level_png, render_level
from dsage_ray.domains.mario.tiles import to_array


def test_one_hot_pads_on_channel_zero(rng):
    levels = rng.integers(0, 17, size=(3, 16, 56))
    x = one_hot_levels(levels)
    assert x.shape == (3, 17, 64, 64) and x.dtype == np.float32
    assert (x.sum(axis=1) == 1).all()
    assert (x[:, :, :16, :56].argmax(axis=1) == levels).all()
    assert (x[:, 0, 16:, :] == 1).all() and (x[:, 0, :, 56:] == 1).all()
    assert one_hot_levels(levels[0]).shape == (1, 17, 64, 64)
    with pytest.raises(ValueError, match="do not fit"):
        one_hot_levels(np.zeros((1, 16, 65), dtype=int))


def test_occupancy_counts_ticks_per_tile_and_averages_runs():
    # Tile (row, col) = (floor(y/16), floor(x/16)); y is at the feet.
    run_a = np.array([[0.0, 223.0], [15.9, 223.0], [16.0, 223.0], [-1.0, 100.0], [900.0, 10.0]], dtype=np.float32)
    run_b = np.array([[40.0, 300.0], [40.0, 10.0]], dtype=np.float32)  # below the level: dropped
    grid = occupancy_grid([run_a, run_b], (16, 56))
    assert grid.dtype == np.float32 and grid.shape == (16, 56)
    assert grid[13, 0] == 1.0  # two ticks over two runs
    assert grid[13, 1] == 0.5
    assert grid[0, 2] == 0.5
    assert grid.sum() == 2.0  # 4 ticks inside the level / 2 runs


def test_render_draws_tiles_path_and_occupancy(flat_level):
    level = to_array(flat_level)
    image = render_level(level, scale=4)
    assert image.shape == (64, 96, 3) and image.dtype == np.uint8
    with_path = render_level(level, scale=4, path=np.array([[8.0, 223.0], [300.0, 223.0]]))
    assert (with_path != image).any()
    occupancy = np.zeros((16, 24), dtype=np.float32)
    occupancy[13, :] = 1
    tinted = render_level(level, scale=4, occupancy=occupancy)
    assert (tinted[13 * 4, 0] != image[13 * 4, 0]).any() and (tinted[0, 0] == image[0, 0]).all()
    assert level_png(level).startswith(b"\x89PNG")
