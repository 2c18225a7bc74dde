import numpy as np
import pytest

from dsage_ray.qd import block_ids, gather_elites, make_archive, select_solutions, skip_filled


def _archive(dims=(32, 27), n=300, seed=0):
    """Random elites with cell coordinates spread over the grid; objective = index (easy to check)."""
    archive = make_archive(solution_dim=2, dims=dims, ranges=[(0, d) for d in dims], occupancy_shape=(2, 2))
    rng = np.random.default_rng(seed)
    measures = rng.uniform(0, 1, size=(n, len(dims))) * np.array(dims)
    archive.add(measures, np.zeros(n), measures, occupancy=np.zeros((n, 2, 2)))
    return archive


def _select(archive, method, seed=0, block=(8, 6), count=10):
    return select_solutions(archive, method=method, block=block, count=count, rng=np.random.default_rng(seed))


def test_full_returns_every_elite():
    archive = _archive()
    np.testing.assert_array_equal(_select(archive, "full"), np.sort(archive.data("index")))


def test_random_count_and_uniqueness():
    archive = _archive()
    picked = _select(archive, "random", count=25)
    assert len(picked) == 25 and len(np.unique(picked)) == 25
    assert set(picked) <= set(archive.data("index"))
    assert len(_select(archive, "random", count=10_000)) == len(archive)


def test_downsample_one_per_occupied_block():
    archive = _archive(dims=(32, 27))  # blocks of 8×6 cells → a 4×5 block grid (last row of blocks is 3 tall)
    picked = _select(archive, "downsample")
    occupied_blocks = np.unique(block_ids(archive, archive.data("index"), (8, 6)))
    picked_blocks = block_ids(archive, picked, (8, 6))
    assert len(picked_blocks) == len(np.unique(picked_blocks))  # at most one per block
    np.testing.assert_array_equal(np.sort(picked_blocks), occupied_blocks)  # exactly one per occupied block
    assert occupied_blocks.max() < 4 * 5


def test_block_ids_match_paper_grids():
    maze = make_archive(solution_dim=1, dims=(256, 162), ranges=[(0, 256), (0, 162)])
    corner = maze.grid_to_int_index([[255, 161]])
    assert block_ids(maze, corner, (8, 6))[0] == 32 * 27 - 1
    mario = make_archive(solution_dim=1, dims=(150, 100), ranges=[(0, 150), (0, 100)])
    assert block_ids(mario, mario.grid_to_int_index([[149, 99]]), (5, 5))[0] == 30 * 20 - 1
    assert block_ids(mario, mario.grid_to_int_index([[5, 4]]), (5, 5))[0] == 1 * 20 + 0


def test_downsample_pick_is_uniform_within_a_block():
    archive = _archive(dims=(4, 4), n=200)  # every cell filled; block 4×4 → one block of 16 elites
    assert len(archive) == 16
    counts = np.bincount([_select(archive, "downsample", seed=s, block=(4, 4))[0] for s in range(1600)], minlength=16)
    assert counts.min() > 60 and counts.max() < 140  # expected 100 each


@pytest.mark.parametrize("method", ["downsample", "random", "full"])
def test_deterministic_for_a_given_rng_and_independent_of_insertion_order(method):
    archive = _archive()
    data = archive.data()
    reordered = make_archive(solution_dim=2, dims=(32, 27), ranges=[(0, 32), (0, 27)], occupancy_shape=(2, 2))
    perm = np.random.default_rng(1).permutation(len(archive))
    reordered.add(data["solution"][perm], data["objective"][perm], data["measures"][perm],
                  occupancy=data["occupancy"][perm])
    np.testing.assert_array_equal(_select(archive, method, seed=4), _select(archive, method, seed=4))
    np.testing.assert_array_equal(_select(archive, method, seed=4), _select(reordered, method, seed=4))
    if method != "full":
        assert not np.array_equal(_select(archive, method, seed=4), _select(archive, method, seed=5))


def test_empty_archive_and_bad_input():
    empty = make_archive(solution_dim=2, dims=(8, 6), ranges=[(0, 1), (0, 1)])
    for method in ("downsample", "random", "full"):
        assert len(_select(empty, method)) == 0
    with pytest.raises(ValueError, match="block"):
        _select(empty, "downsample", block=(8,))
    with pytest.raises(ValueError, match="unknown method"):
        _select(empty, "best")


def test_gather_elites_returns_fields_in_requested_order():
    archive = _archive()
    picked = _select(archive, "random", count=5)[::-1]
    elites = gather_elites(archive, picked)
    np.testing.assert_array_equal(elites["index"], picked)
    np.testing.assert_array_equal(archive.index_of(elites["measures"]), picked)
    assert elites["occupancy"].shape == (5, 2, 2)
    free = np.setdiff1d(np.arange(archive.cells), archive.data("index"))[:1]
    with pytest.raises(KeyError):
        gather_elites(archive, free)


def _grid_archive(cells_and_objectives, *, dims=(4, 4), occupancy=True):
    """An archive over [0, 4)² holding one elite per ``((row, col), objective)``; solution = cell."""
    archive = make_archive(solution_dim=2, dims=dims, ranges=[(0, d) for d in dims],
                           occupancy_shape=(2, 2) if occupancy else None)
    if cells_and_objectives:
        cells = np.array([c for c, _ in cells_and_objectives], dtype=float) + 0.5  # cell centres
        objective = np.array([o for _, o in cells_and_objectives], dtype=float)
        extra = {"occupancy": np.zeros((len(cells), 2, 2))} if occupancy else {}
        archive.add(cells, objective, cells, **extra)
    return archive


def _cell_index(archive, cell):
    return int(archive.grid_to_int_index([cell])[0])


def test_skip_filled_drops_picks_the_ground_truth_archive_already_beats():
    ground_truth = _grid_archive([((0, 0), 1.0), ((1, 1), 0.5), ((3, 3), 0.7)])
    # Surrogate predictions: (0,0) worse than its filled cell, (1,1) better, (2,2) an empty cell,
    # (3,3) exactly as good (at least as well: dropped).
    surrogate = _grid_archive([((0, 0), 0.8), ((1, 1), 0.9), ((2, 2), 0.1), ((3, 3), 0.7)], occupancy=False)
    picks = np.sort(surrogate.data("index"))[::-1]  # any order in, sorted out
    result = skip_filled(surrogate, picks, ground_truth)
    expected = sorted(_cell_index(surrogate, c) for c in [(1, 1), (2, 2)])
    assert result.kept.tolist() == expected
    assert result.filled == 2 and not result.fallback


def test_skip_filled_reads_the_predicted_cell_not_the_solution():
    ground_truth = _grid_archive([((2, 2), 1.0)])
    surrogate = make_archive(solution_dim=2, dims=(4, 4), ranges=[(0, 4), (0, 4)])
    # Solution says (0, 0) (empty in the ground truth), but it is predicted to land in (2, 2).
    surrogate.add([[0.5, 0.5]], [0.3], [[2.5, 2.5]])
    result = skip_filled(surrogate, surrogate.data("index"), ground_truth)
    assert result.fallback and result.filled == 1  # its only pick is dominated: kept as the fallback


def test_skip_filled_keeps_every_pick_when_all_are_dominated_and_handles_nothing():
    ground_truth = _grid_archive([((0, 0), 1.0), ((1, 1), 1.0)])
    surrogate = _grid_archive([((0, 0), 0.9), ((1, 1), 1.0)], occupancy=False)
    picks = surrogate.data("index")
    result = skip_filled(surrogate, picks, ground_truth)
    assert result.fallback and result.filled == 2
    assert result.kept.tolist() == sorted(picks.tolist())

    nothing = skip_filled(surrogate, np.empty(0, dtype=np.int64), ground_truth)
    assert len(nothing.kept) == 0 and nothing.filled == 0 and not nothing.fallback

    empty_truth = _grid_archive([])
    everything = skip_filled(surrogate, picks, empty_truth)
    assert everything.kept.tolist() == sorted(picks.tolist()) and everything.filled == 0


def test_skip_filled_after_downsampling_and_bad_input():
    ground_truth = _grid_archive([((r, c), 1.0) for r in range(2) for c in range(4)])  # top half filled
    surrogate = _grid_archive([((r, c), 0.5) for r in range(4) for c in range(4)], occupancy=False)
    picks = _select(surrogate, "downsample", block=(2, 2))  # one per 2×2 block: 4 picks
    result = skip_filled(surrogate, picks, ground_truth)
    kept_rows = surrogate.int_to_grid_index(result.kept)[:, 0]
    assert len(picks) == 4 and result.filled == 2 and kept_rows.min() >= 2
    with pytest.raises(ValueError, match="same cells"):
        skip_filled(surrogate, picks, _grid_archive([], dims=(4, 2)))
    with pytest.raises(KeyError):
        skip_filled(_grid_archive([], occupancy=False), [3], ground_truth)


def test_downsample_prefers_the_cells_a_given_archive_lacks():
    # One 2x2 block: (0,0), (0,1) and (1,0) are held by the ground truth, (1,1) is not.
    ground_truth = _grid_archive([((0, 0), 1.0), ((0, 1), 0.0), ((1, 0), 0.2)])
    surrogate = _grid_archive([((0, 0), 0.5), ((0, 1), 0.5), ((1, 0), 0.5), ((1, 1), 0.5), ((2, 2), 0.5),
                               ((3, 3), 0.5)], occupancy=False)
    new = _cell_index(surrogate, (1, 1))
    for seed in range(20):
        picks = select_solutions(surrogate, method="downsample", block=(2, 2), count=0,
                                 rng=np.random.default_rng(seed), new_cells=ground_truth)
        assert new in picks.tolist() and len(picks) == 2  # blocks (0,0) and (1,1)
    # A block whose every cell is held still gets its uniform pick.
    full_block = _grid_archive([((0, 0), 1.0), ((0, 1), 1.0), ((1, 0), 1.0), ((1, 1), 1.0)])
    seen = {int(select_solutions(surrogate, method="downsample", block=(2, 2), count=0, rng=np.random.default_rng(s),
                                 new_cells=full_block)[0]) for s in range(40)}
    assert seen == {_cell_index(surrogate, c) for c in [(0, 0), (0, 1), (1, 0), (1, 1)]}


def test_new_cells_needs_downsampling_and_the_same_cells():
    surrogate = _grid_archive([((0, 0), 0.5)], occupancy=False)
    with pytest.raises(ValueError, match="downsampling only"):
        select_solutions(surrogate, method="random", block=(2, 2), count=1, rng=np.random.default_rng(0),
                         new_cells=_grid_archive([]))
    with pytest.raises(ValueError, match="same cells"):
        select_solutions(surrogate, method="downsample", block=(2, 2), count=0, rng=np.random.default_rng(0),
                         new_cells=_grid_archive([], dims=(4, 2)))
