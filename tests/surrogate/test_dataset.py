"""The surrogate dataset: bit-packed storage, the training window, failed results, checkpoints."""

import pickle

import numpy as np
import pytest
import torch

from dsage_ray.surrogate.dataset import SurrogateDataset
from dsage_ray.types import EvaluationResult
from tests.surrogate.helpers import random_levels, toy_results

SHAPE = (5, 8, 8)
OCC = (6, 7)


def make(**kwargs):
    return SurrogateDataset(level_shape=SHAPE, num_measures=2, occupancy_shape=OCC, **kwargs)


def filled(n_batches=5, batch=7):
    dataset = make()
    levels = random_levels(n_batches * batch, size=8)
    for b in range(n_batches):
        chunk = levels[b * batch:(b + 1) * batch]
        dataset.append(encoded=chunk, results=toy_results(chunk, OCC))
    return dataset, levels


def test_append_grows_and_round_trips_levels_exactly():
    dataset, levels = filled()
    assert len(dataset) == len(levels)
    assert np.array_equal(dataset.levels(), levels)
    assert np.allclose(dataset.objective, [lvl[1].mean() for lvl in levels])
    assert dataset.occupancy.shape == (len(levels), *OCC)


def test_recent_is_the_last_k_samples_in_order():
    dataset, levels = filled()
    window = dataset.recent(10)
    assert len(window) == 10
    idx = np.array([9, 0, 4])
    got_levels, objective, measures, occupancy = window.batch(idx, torch.device("cpu"))
    tail = levels[-10:][idx]
    expected = toy_results(tail, OCC)
    assert torch.equal(got_levels, torch.from_numpy(tail))
    assert np.allclose(objective.numpy(), [r.objective for r in expected])
    assert np.allclose(measures.numpy(), [r.measures for r in expected])
    assert np.array_equal(occupancy.numpy(), np.stack([r.occupancy for r in expected]))
    assert len(dataset.recent(1000)) == len(dataset)


def test_failed_results_are_not_stored():
    dataset = make()
    levels = random_levels(4, size=8)
    results = toy_results(levels, OCC)
    results[1] = EvaluationResult.failure(error="boom", num_measures=2, occupancy_shape=OCC)
    assert dataset.append(encoded=levels, results=results) == 3
    assert np.array_equal(dataset.levels(), levels[[0, 2, 3]])


def test_rejects_wrong_shapes_and_non_binary_levels():
    dataset = make()
    levels = random_levels(2, size=8)
    with pytest.raises(ValueError):
        dataset.append(encoded=levels[:, :, :4], results=toy_results(levels, OCC))
    with pytest.raises(ValueError, match="one-hot"):
        dataset.append(encoded=levels * 0.5, results=toy_results(levels, OCC))


def test_state_dict_round_trip_through_pickle():
    dataset, levels = filled()
    restored = make()
    restored.load_state_dict(pickle.loads(pickle.dumps(dataset.state_dict())))
    assert len(restored) == len(dataset)
    assert np.array_equal(restored.levels(), levels)
    for key in ("objective", "measures", "occupancy"):
        assert np.array_equal(getattr(restored, key), getattr(dataset, key))
    # The restored dataset keeps accepting data.
    more = random_levels(3, size=8, seed=1)
    restored.append(encoded=more, results=toy_results(more, OCC))
    assert np.array_equal(restored.levels(slice(-3, None)), more)


def test_state_dict_is_a_snapshot():
    dataset, _ = filled(n_batches=1)
    state = dataset.state_dict()
    more = random_levels(3, size=8, seed=1)
    dataset.append(encoded=more, results=toy_results(more, OCC))
    assert len(state["objective"]) == 7


def test_keeps_solutions_when_asked():
    dataset = make(solution_dim=3, solution_dtype=np.uint8)
    levels = random_levels(2, size=8)
    dataset.append(encoded=levels, results=toy_results(levels, OCC), solutions=np.array([[1, 0, 1], [0, 1, 1]]))
    assert dataset.solutions.dtype == np.uint8
    assert np.array_equal(dataset.solutions, [[1, 0, 1], [0, 1, 1]])
    with pytest.raises(ValueError, match="solutions"):
        dataset.append(encoded=levels, results=toy_results(levels, OCC))
