import numpy as np
import pytest

from dsage_ray.qd import block_ids, gather_elites, make_archive, select_solutions
from dsage_ray.qd.selection import additions, adds_to


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


@pytest.mark.parametrize("method", ["downsample", "random", "full"])
def test_among_restricts_every_method_to_the_given_elites(method):
    archive = _archive()
    among = np.sort(archive.data("index"))[::3]
    picked = select_solutions(archive, method=method, block=(8, 6), count=10_000, rng=np.random.default_rng(0),
                              among=among)
    assert len(picked) and set(picked) <= set(among)
    if method == "full":
        np.testing.assert_array_equal(picked, among)


def test_downsample_with_priority_picks_each_blocks_highest():
    archive = _archive(dims=(8, 8), n=500)  # every cell filled; blocks of 4×4 → four blocks
    among = np.sort(archive.data("index"))
    priority = np.random.default_rng(1).random(len(among))
    picked = select_solutions(archive, method="downsample", block=(4, 4), count=0, rng=np.random.default_rng(0),
                              among=among, priority=priority)
    blocks = block_ids(archive, among, (4, 4))
    best = [among[blocks == b][np.argmax(priority[blocks == b])] for b in np.unique(blocks)]
    np.testing.assert_array_equal(picked, np.sort(best))
    with pytest.raises(ValueError, match="one value per index"):
        select_solutions(archive, method="downsample", block=(4, 4), count=0, rng=np.random.default_rng(0),
                         among=among, priority=priority[:3])


def test_additions_say_what_enters_and_what_it_adds_to_the_qd_score():
    archive = make_archive(solution_dim=1, dims=(4,), ranges=[(0, 4)])  # QD-score offset 0
    archive.add(np.zeros((1, 1)), np.array([0.5]), np.array([[0.5]]))  # cell 0 holds 0.5; cells 1-3 are empty
    objective = np.array([0.7, 0.2, 0.5, -2.0])
    measures = np.array([[0.5], [0.5], [0.5], [2.5]])
    adding, gain = additions(archive, objective, measures)
    np.testing.assert_array_equal(adding, [True, False, False, True])  # a tie does not enter; an empty cell does
    np.testing.assert_allclose(gain, [0.2, -0.3, 0.0, -2.0])  # the empty cell's gain counts from the offset
    np.testing.assert_array_equal(adds_to(archive, objective, measures), adding)
