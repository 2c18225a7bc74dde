import numpy as np
import pytest

from dsage_ray.qd import make_archive
from dsage_ray.qd.gain import PickErrors
from dsage_ray.qd.screen import keep_screened, screen_picks
from dsage_ray.qd.selection import gather_elites

DIMS = (20, 20)


def _archive(measures, objective=None):
    """An archive over a 20 × 20 grid of unit cells whose solutions are their measures (easy to screen)."""
    archive = make_archive(solution_dim=2, dims=DIMS, ranges=[(0, d) for d in DIMS])
    measures = np.asarray(measures, dtype=np.float64).reshape(-1, 2)
    if len(measures):
        archive.add(measures, np.zeros(len(measures)) if objective is None else np.asarray(objective, np.float64),
                    measures)
    return archive


def _surrogate_archive():
    """One elite per cell of the 10 × 10 lower-left quarter: predicted measures = solution."""
    cells = np.array([(i + 0.5, j + 0.5) for i in range(10) for j in range(10)])
    return _archive(cells)


def _shifted(dx):
    """A screen that says each level really lands ``dx`` cells to the right of its predicted cell."""
    calls = []

    def screen(solutions):
        calls.append(len(solutions))
        return np.zeros(len(solutions)), np.asarray(solutions, np.float64) + [dx, 0.0]

    return screen, calls


def _indices(archive, measures):
    return np.sort(archive.index_of(np.asarray(measures, np.float64)))


def test_a_pick_whose_screen_lands_in_a_filled_cell_gives_way_to_one_that_lands_in_an_empty_cell():
    surrogate = _surrogate_archive()
    # The ground truth holds every cell of columns 0-9 except (5, 5): a level screened there is the only new one.
    ground_truth = _archive([(i + 0.5, j + 0.5) for i in range(10) for j in range(10) if (i, j) != (5, 5)])
    picks = _indices(surrogate, [(1.5, 1.5), (2.5, 2.5)])
    screen, calls = _shifted(0.0)
    result = screen_picks(surrogate, picks, ground_truth, screen=screen, pool=100, rng=np.random.default_rng(0))
    # The extra candidates are the elites predicted to add: here only (5, 5), however large the pool.
    assert calls == [3]
    np.testing.assert_array_equal(result.kept, _indices(surrogate, [(5.5, 5.5)]))
    assert (result.screened, result.new, result.fallback) == (3, 1, False)


def test_it_reads_the_screened_cell_not_the_predicted_one():
    surrogate = _surrogate_archive()
    # Predicted cells are all empty; screened ones (10 columns to the right) are all filled but (13, 4).
    ground_truth = _archive([(i + 10.5, j + 0.5) for i in range(10) for j in range(10) if (i, j) != (3, 4)])
    picks = _indices(surrogate, [(0.5, 0.5), (1.5, 0.5), (2.5, 0.5)])
    screen, _ = _shifted(10.0)
    result = screen_picks(surrogate, picks, ground_truth, screen=screen, pool=100, rng=np.random.default_rng(0))
    np.testing.assert_array_equal(result.kept, _indices(surrogate, [(3.5, 4.5)]))


def test_picks_come_first_and_no_more_than_the_picks_are_kept_one_per_screened_cell():
    surrogate = _surrogate_archive()
    ground_truth = _archive(np.empty((0, 2)))
    picks = _indices(surrogate, [(0.5, 0.5), (9.5, 9.5), (4.5, 4.5)])

    def collapse(solutions):  # every level but the last pick really lands in cell (19, 19)
        measures = np.full((len(solutions), 2), 19.5)
        measures[np.all(np.asarray(solutions) == [9.5, 9.5], axis=1)] = [0.5, 19.5]
        return np.zeros(len(solutions)), measures

    result = screen_picks(surrogate, picks, ground_truth, screen=collapse, pool=4, rng=np.random.default_rng(0))
    assert result.screened == 12  # 3 picks × 4
    # Two screened cells, each taken by its first candidate; the picks come before the extra candidates.
    np.testing.assert_array_equal(result.kept, _indices(surrogate, [(0.5, 0.5), (9.5, 9.5)]))


def test_extra_candidates_are_only_elites_predicted_to_add_and_a_higher_objective_adds():
    surrogate = _archive([(0.5, 0.5), (1.5, 0.5), (2.5, 0.5)], objective=[1.0, 1.0, 1.0])
    # The ground truth holds (1, 0) with a lower objective (so the elite there would add) and (2, 0) with a higher.
    ground_truth = _archive([(1.5, 0.5), (2.5, 0.5)], objective=[0.5, 2.0])
    picks = _indices(surrogate, [(0.5, 0.5)])
    seen = []

    def screen(solutions):
        seen.extend(map(tuple, np.asarray(solutions)))
        return np.ones(len(solutions)), np.asarray(solutions, np.float64)

    result = screen_picks(surrogate, picks, ground_truth, screen=screen, pool=10, rng=np.random.default_rng(0))
    assert set(seen) == {(0.5, 0.5), (1.5, 0.5)}  # (2.5, 0.5) is predicted not to beat its ground-truth elite
    assert result.new == 2 and len(result.kept) == 1  # both would add; one pick's worth is kept: the pick
    np.testing.assert_array_equal(result.kept, picks)


def test_when_nothing_screened_would_add_the_picks_are_kept_and_nothing_in_nothing_out():
    surrogate = _surrogate_archive()
    ground_truth = _archive([(i + 0.5, j + 0.5) for i in range(20) for j in range(20)])
    picks = _indices(surrogate, [(1.5, 1.5), (2.5, 2.5)])
    screen, _ = _shifted(3.0)
    result = screen_picks(surrogate, picks, ground_truth, screen=screen, pool=2, rng=np.random.default_rng(0))
    np.testing.assert_array_equal(result.kept, picks)
    assert result.fallback and result.new == 0
    empty = screen_picks(surrogate, np.empty(0, np.int64), ground_truth, screen=screen, pool=2,
                         rng=np.random.default_rng(0))
    assert len(empty.kept) == 0 and empty.screened == 0


def test_bad_input():
    surrogate = _surrogate_archive()
    screen, _ = _shifted(0.0)
    with pytest.raises(ValueError, match="pool must be at least 1"):
        screen_picks(surrogate, np.empty(0, np.int64), surrogate, screen=screen, pool=0.5, rng=np.random.default_rng(0))
    other = make_archive(solution_dim=2, dims=(10, 10), ranges=[(0, 20), (0, 20)])
    with pytest.raises(ValueError, match="same cells"):
        screen_picks(surrogate, np.empty(0, np.int64), other, screen=screen, pool=1, rng=np.random.default_rng(0))


def _valid(dx):
    """As :func:`_shifted`, for levels of objective 1, which add 1 to the QD-score in an empty cell (as a valid maze)."""
    def screen(solutions):
        return np.ones(len(solutions)), np.asarray(solutions, np.float64) + [dx, 0.0]

    return screen


def _errors(shifts):
    """The screen's recent errors: each level screened at (0.5, 0.5) really landed ``shift`` cells to the right."""
    errors = PickErrors(window=100)
    shifts = np.asarray(shifts, np.float64)
    screened = np.tile([0.5, 0.5], (len(shifts), 1))
    errors.add(predicted_objective=np.ones(len(shifts)), predicted_measures=screened,
               objective=np.ones(len(shifts)), measures=screened + np.column_stack([shifts, np.zeros(len(shifts))]))
    return errors


def test_with_the_screens_errors_a_level_expected_to_land_in_a_filled_cell_gives_way_to_one_expected_in_an_empty_one():
    surrogate = _surrogate_archive()
    # (1, 1) is empty but the screen's errors move it to the filled (4, 1); (2, 2) is filled, its errors move it to
    # the empty (5, 2).
    ground_truth = _archive([(4.5, 1.5), (2.5, 2.5)], objective=[1.0, 1.0])
    picks = _indices(surrogate, [(1.5, 1.5), (2.5, 2.5)])
    screen = _valid(0.0)
    ranked = screen_picks(surrogate, picks, ground_truth, screen=screen, pool=1, rng=np.random.default_rng(0),
                          errors=_errors([3.0]), neighbours=8)
    np.testing.assert_array_equal(ranked.kept, _indices(surrogate, [(2.5, 2.5)]))
    assert ranked.new == 1 and ranked.expected_new == 1.0  # the screened cell alone says (1, 1) is the new one
    by_cell = screen_picks(surrogate, picks, ground_truth, screen=screen, pool=1, rng=np.random.default_rng(0))
    np.testing.assert_array_equal(by_cell.kept, _indices(surrogate, [(1.5, 1.5)]))
    assert np.isnan(by_cell.expected_new)


def test_the_candidates_expected_to_add_most_are_kept_first_whatever_their_order():
    solutions = np.array([(1.5, 1.5), (1.5, 2.5), (1.5, 3.5)])
    # Half the screen's errors are +3 cells: (4, 1) and (4, 2) are filled, so the first two are expected to add 0.5.
    ground_truth = _archive([(4.5, 1.5), (4.5, 2.5)], objective=[1.0, 1.0])
    screen = _valid(0.0)
    result = keep_screened(solutions, ground_truth, screen=screen, limit=1, errors=_errors([0.0, 3.0]), neighbours=2)
    np.testing.assert_array_equal(result.kept, [2])
    assert result.expected_new == 1.0
    result = keep_screened(solutions, ground_truth, screen=screen, limit=2, errors=_errors([0.0, 3.0]), neighbours=2)
    np.testing.assert_array_equal(result.kept, [0, 2])  # ties go to the earlier candidate
    np.testing.assert_array_equal(result.estimates, np.column_stack([np.ones(3), solutions]))


def test_with_no_errors_recorded_yet_the_screened_cell_decides_as_without_them():
    rng = np.random.default_rng(3)
    solutions = rng.uniform(0, 20, (60, 2))
    ground_truth = _archive(rng.uniform(0, 20, (150, 2)), objective=np.ones(150))
    screen = _valid(0.0)
    plain = keep_screened(solutions, ground_truth, screen=screen, limit=25)
    empty = keep_screened(solutions, ground_truth, screen=screen, limit=25, errors=PickErrors(window=10))
    assert 0 < len(plain.kept) <= 25
    np.testing.assert_array_equal(empty.kept, plain.kept)
    assert empty.new == plain.new


def test_screen_picks_returns_the_kept_ones_screened_results_in_their_order():
    surrogate = _surrogate_archive()
    ground_truth = _archive(np.empty((0, 2)))
    picks = _indices(surrogate, [(0.5, 0.5), (9.5, 9.5), (4.5, 4.5)])
    screen = _valid(5.0)
    result = screen_picks(surrogate, picks, ground_truth, screen=screen, pool=1, rng=np.random.default_rng(0))
    solutions = gather_elites(surrogate, result.kept)["solution"]
    np.testing.assert_array_equal(result.estimates[:, 1:], solutions + [5.0, 0.0])


def test_with_a_cost_the_candidate_expected_to_add_most_per_cost_comes_first():
    from dsage_ray.qd.gain import EvaluationCost

    # Both would fill an empty cell; the first lies where evaluations have cost 1 + 15.5, the second 1 + 1.5.
    solutions = np.array([(15.5, 0.5), (1.5, 0.5)])
    errors = PickErrors(window=10)
    errors.add(predicted_objective=np.ones(2), predicted_measures=solutions, objective=np.ones(2), measures=solutions)
    ground_truth = _archive(np.empty((0, 2)))
    screen = _valid(0.0)
    by_gain = keep_screened(solutions, ground_truth, screen=screen, limit=1, errors=errors, neighbours=1)
    np.testing.assert_array_equal(by_gain.kept, [0])
    per_cost = keep_screened(solutions, ground_truth, screen=screen, limit=1, errors=errors, neighbours=1,
                             cost=EvaluationCost(measure=0, offset=1.0))
    np.testing.assert_array_equal(per_cost.kept, [1])
    assert per_cost.expected_new == 1.0
