import numpy as np
import pytest

from dsage_ray.qd import make_archive
from dsage_ray.qd.gain import EvaluationCost, PickErrors, expected_outcomes


def _line(filled: dict[int, float], cells: int = 8):
    """A one-measure archive over [0, cells) with one cell per unit; ``filled`` maps cell → objective."""
    archive = make_archive(solution_dim=1, dims=(cells,), ranges=[(0, cells)])
    if filled:
        centres = np.array(sorted(filled), dtype=float)[:, None] + 0.5
        archive.add(centres, np.array([filled[c] for c in sorted(filled)]), centres)
    return archive


def _errors(predicted_measure, actual_measure, *, predicted_objective=None, objective=None, window=100):
    errors = PickErrors(window=window)
    n = len(predicted_measure)
    errors.add(predicted_objective=np.ones(n) if predicted_objective is None else predicted_objective,
               predicted_measures=np.asarray(predicted_measure, float)[:, None],
               objective=np.ones(n) if objective is None else objective,
               measures=np.asarray(actual_measure, float)[:, None])
    return errors


def test_pick_errors_keep_the_latest_window_and_round_trip():
    errors = _errors([0.5, 1.5, 2.5], [1.0, 2.0, 3.0], window=4)
    errors.add(predicted_objective=np.zeros(2), predicted_measures=np.array([[4.5], [5.5]]),
               objective=np.zeros(2), measures=np.array([[4.0], [5.0]]))
    assert len(errors) == 4
    np.testing.assert_array_equal(errors.predicted[:, 1], [1.5, 2.5, 4.5, 5.5])  # the oldest pick left
    np.testing.assert_array_equal(errors.actual[:, 1], [2.0, 3.0, 4.0, 5.0])
    restored = PickErrors.from_state_dict(errors.state_dict())
    np.testing.assert_array_equal(restored.predicted, errors.predicted)
    assert restored.window == 4


def test_pick_errors_refuse_mismatched_picks():
    errors = _errors([0.5], [1.0])
    with pytest.raises(ValueError, match="shape"):
        errors.add(predicted_objective=np.ones(2), predicted_measures=np.ones((2, 1)), objective=np.ones(1),
                   measures=np.ones((1, 1)))
    with pytest.raises(ValueError, match="measures"):
        errors.add(predicted_objective=np.ones(1), predicted_measures=np.ones((1, 2)), objective=np.ones(1),
                   measures=np.ones((1, 2)))
    with pytest.raises(ValueError, match="window"):
        PickErrors(window=0)


def test_a_candidate_gains_the_share_of_its_error_samples_that_land_in_empty_cells():
    truth = _line({0: 1.0, 1: 1.0})
    # Errors of 0 and +1 cell, each half the time: from cell 1 one sample stays, one lands in empty cell 2.
    errors = _errors([3.5, 3.5], [3.5, 4.5])
    gains = expected_outcomes(np.ones(3), np.array([[0.5], [1.5], [5.5]]), ground_truth_archive=truth, errors=errors,
                           neighbours=2).gain
    np.testing.assert_allclose(gains, [0.0, 0.5, 1.0])


def test_an_occupied_cell_adds_only_the_improvement_and_samples_past_the_edge_land_in_the_edge_cell():
    truth = _line({7: 0.25})
    errors = _errors([1.0], [30.0])  # a huge error: lands past the upper edge, in cell 7
    gains = expected_outcomes(np.array([1.0, 0.1]), np.array([[1.0], [1.0]]), ground_truth_archive=truth,
                           errors=errors, neighbours=1).gain
    np.testing.assert_allclose(gains, [0.75, 0.0])  # beats 0.25 by 0.75; a worse one adds nothing


def test_objective_errors_move_the_sampled_objective():
    truth = _line({})
    errors = _errors([2.5], [2.5], predicted_objective=np.array([1.0]), objective=np.array([0.4]))
    gains = expected_outcomes(np.array([1.0]), np.array([[5.5]]), ground_truth_archive=truth, errors=errors,
                           neighbours=1).gain
    np.testing.assert_allclose(gains, [0.4])  # predicted 1.0, off by -0.6 the last time


def test_a_candidate_borrows_the_errors_of_picks_predicted_near_it():
    truth = _line({0: 1.0, 1: 1.0})
    # Picks predicted low were right; picks predicted high landed 6 cells lower, in filled cell 0 or 1.
    errors = _errors([2.2, 2.4, 6.8, 7.2], [2.2, 2.4, 0.8, 1.2])
    gains = expected_outcomes(np.ones(2), np.array([[2.5], [7.0]]), ground_truth_archive=truth, errors=errors,
                           neighbours=2).gain
    np.testing.assert_allclose(gains, [1.0, 0.0])
    everyone = expected_outcomes(np.ones(2), np.array([[2.5], [7.0]]), ground_truth_archive=truth, errors=errors,
                              neighbours=50).gain  # more neighbours than picks: all four
    np.testing.assert_allclose(everyone, [0.5, 0.5])  # half of the errors are -6 cells, for both


def test_without_a_cost_every_candidate_costs_the_same():
    errors = _errors([2.2, 6.8], [2.2, 0.8])
    outcomes = expected_outcomes(np.ones(2), np.array([[2.5], [7.0]]), ground_truth_archive=_line({}), errors=errors,
                                 neighbours=1)
    np.testing.assert_allclose(outcomes.cost, [1.0, 1.0])
    np.testing.assert_allclose(outcomes.gain_per_cost, outcomes.gain)


def test_the_cost_is_that_of_the_neighbours_real_evaluations_relative_to_the_recent_mean():
    # Picks predicted at 1 really measured 1; those predicted at 6 really measured 7. With an offset
    # of 1, they cost 2 and 8: the mean is 5.
    errors = _errors([1.0, 1.0, 6.0, 6.0], [1.0, 1.0, 7.0, 7.0])
    outcomes = expected_outcomes(np.ones(2), np.array([[1.2], [5.8]]), ground_truth_archive=_line({}),
                                 errors=errors, neighbours=2, cost=EvaluationCost(measure=0, offset=1.0))
    np.testing.assert_allclose(outcomes.cost, [2 / 5, 8 / 5])
    np.testing.assert_allclose(outcomes.gain, [1.0, 1.0])
    np.testing.assert_allclose(outcomes.gain_per_cost, [2.5, 0.625])
    with pytest.raises(ValueError, match="positive"):
        EvaluationCost(measure=0, offset=0.0)
    with pytest.raises(ValueError, match="cost measure"):
        expected_outcomes(np.ones(1), np.ones((1, 1)), ground_truth_archive=_line({}), errors=errors, neighbours=1,
                          cost=EvaluationCost(measure=1, offset=1.0))


def test_before_any_pick_is_evaluated_the_predictions_are_taken_as_exact():
    # Cell 1 holds 2.0: a candidate predicted there at 3.0 adds 1.0, one at 1.5 adds nothing, one in empty
    # cell 4 adds its objective (the offset is 0). Costs follow the predicted measure over the candidates' mean.
    truth = _line({1: 2.0})
    outcomes = expected_outcomes(np.array([3.0, 1.5, 0.5]), np.array([[1.5], [1.2], [4.5]]), ground_truth_archive=truth,
                                 errors=PickErrors(window=3), neighbours=4, cost=EvaluationCost(measure=0, offset=0.5))
    np.testing.assert_allclose(outcomes.gain, [1.0, 0.0, 0.5])
    np.testing.assert_allclose(outcomes.cost, np.array([2.0, 1.7, 5.0]) / np.mean([2.0, 1.7, 5.0]))
    plain = expected_outcomes(np.array([3.0]), np.array([[1.5]]), ground_truth_archive=truth,
                              errors=PickErrors(window=3), neighbours=1)
    np.testing.assert_allclose(plain.cost, [1.0])


def test_expected_outcomes_bad_input():
    truth = _line({})
    with pytest.raises(ValueError, match="neighbours"):
        expected_outcomes(np.ones(1), np.ones((1, 1)), ground_truth_archive=truth, errors=_errors([1.0], [1.0]),
                       neighbours=0)
    with pytest.raises(ValueError, match="measures"):
        expected_outcomes(np.ones(1), np.ones((1, 2)), ground_truth_archive=truth, errors=_errors([1.0], [1.0]),
                       neighbours=1)


def _surrogate_archive():
    """Eight elites, one per cell of a 4 × 2 grid; blocks of 2 × 2 cells make two blocks."""
    archive = make_archive(solution_dim=2, dims=(4, 2), ranges=[(0, 4), (0, 2)])
    cells = np.array([[x, y] for x in range(4) for y in range(2)], dtype=float) + 0.5
    archive.add(cells, np.ones(len(cells)), cells)
    return archive


def _gains_by_cell(archive, by_cell):
    measures = archive.data("measures")
    return np.array([by_cell.get(tuple(np.floor(m).astype(int)), 0.0) for m in measures])
