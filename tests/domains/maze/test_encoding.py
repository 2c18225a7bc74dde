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


def test_path_channels_mark_reachable_cells_and_every_shortest_path_cell():
    from dsage_ray.domains.maze.encoding import PATH_CHANNELS
    from dsage_ray.domains.maze.level import path_distances

    rng = np.random.default_rng(3)
    solutions = (rng.random((40, 9 * 7)) < 0.35).astype(np.int8)
    encoded = encode_levels(solutions, 9, 7, path_channels=True)
    assert encoded.shape == (40, len(CHANNELS) + len(PATH_CHANNELS), 9, 7)
    assert np.array_equal(encoded[:, :len(CHANNELS)], encode_levels(solutions, 9, 7))
    levels = [MazeLevel.from_bitmap(s.reshape(9, 7)) for s in solutions]
    assert np.array_equal(encode_levels(levels, 9, 7, path_channels=True), encoded)
    reachable, on_path = encoded[:, len(CHANNELS)], encoded[:, len(CHANNELS) + 1]
    checked = 0
    for level, reach, path in zip(levels, reachable, on_path):
        if not level.valid:
            assert not reach.any() and not path.any()
            continue
        from_start, to_goal = path_distances(level.walls, level.start), path_distances(level.walls, level.goal)
        assert np.array_equal(reach > 0, np.isfinite(from_start))
        assert np.array_equal(path > 0, np.isfinite(from_start) & (from_start + to_goal == from_start[level.goal]))
        assert path.sum() >= level.optimal_path_length + 1  # at least one whole path, both ends included
        checked += 1
    assert checked > 20


def test_maze_domain_reads_path_channels_from_its_config():
    from dsage_ray.domains.maze.domain import MazeDomain
    from dsage_ray.domains.maze.plugin import MazeConfig

    plain, with_paths = MazeDomain(config=MazeConfig()), MazeDomain(config=MazeConfig(path_channels=True))
    solutions = plain.random_solutions(3, np.random.default_rng(0))
    assert plain.encode(solutions).shape[1] == plain.encoding_channels == 5
    assert with_paths.encode(solutions).shape[1] == with_paths.encoding_channels == 7
