"""Training, prediction, determinism and exact resume of the Surrogate."""

import pickle

import numpy as np
import pytest
import torch

from dsage_ray.config import SurrogateConfig
from dsage_ray.surrogate import Surrogate
from dsage_ray.types import EvaluationResult
from tests.surrogate.helpers import random_levels, toy_results

# Tiny inputs keep these tests fast on a shared 2-core machine: 8x8 levels, a 6x7 occupancy region.
OCC = (6, 7)


def make(kind="two_stage", seed=0, **config):
    # fp32 unless a test asks: "auto" would make these tests depend on the CPU they run on.
    config = SurrogateConfig(**{"epochs": 1, "batch_size": 16, "device": "cpu", "precision": "fp32", **config})
    return Surrogate(kind=kind, input_channels=5, input_shape=(8, 8), occupancy_shape=OCC, num_measures=2,
                     config=config, seed=seed)


def toy_dataset(surrogate, n=64, seed=0):
    dataset = surrogate.make_dataset()
    levels = random_levels(n, size=8, seed=seed)
    dataset.append(encoded=levels, results=toy_results(levels, OCC))
    return dataset, levels


@pytest.mark.parametrize("kind", ["two_stage", "one_stage"])
def test_training_reduces_loss_on_a_learnable_task(kind):
    surrogate = make(kind, epochs=3, lr=3e-3)
    dataset, levels = toy_dataset(surrogate)
    first = surrogate.train(dataset)
    for _ in range(4):
        last = surrogate.train(dataset)
    assert set(first) == {*surrogate.head_names, "total", "epochs"} and first["epochs"] == 3
    assert last["total"] < 0.5 * first["total"]
    # Held-out levels: the model learned the task, not the samples.
    held_out = random_levels(32, size=8, seed=99)
    before = make(kind).mae(held_out, toy_results(held_out, OCC))
    after = surrogate.mae(held_out, toy_results(held_out, OCC))
    assert after["measure_0"] < before["measure_0"]


def test_loss_is_mean_head_mse_plus_weighted_occupancy():
    surrogate = make(occupancy_weight=10.0, lr=1e-12)  # lr ~0: the last epoch's losses match the untrained model
    dataset, _ = toy_dataset(surrogate, n=16)
    losses = surrogate.train(dataset)
    heads = np.mean([losses["objective"], losses["measure_0"], losses["measure_1"]])
    assert losses["total"] == pytest.approx(heads + 10.0 * losses["occupancy"], rel=1e-5)


@pytest.mark.parametrize("precision", ["fp32", "bf16"])
def test_prediction_shapes_and_chunking(precision, monkeypatch):
    import dsage_ray.surrogate.surrogate as surrogate_module

    levels = random_levels(10, size=8)
    whole = make(precision=precision).predict(levels)
    monkeypatch.setattr(surrogate_module, "PREDICT_BATCH_SIZE", 3)
    chunked = make(precision=precision).predict(levels)
    assert whole.objective.shape == (10,) and whole.measures.shape == (10, 2)
    assert whole.occupancy.shape == (10, *OCC)
    for a, b in zip((whole.objective, whole.measures, whole.occupancy),
                    (chunked.objective, chunked.measures, chunked.occupancy)):
        np.testing.assert_allclose(a, b, rtol=1e-5, atol=1e-6)
    empty = make().predict(levels[:0])
    assert empty.objective.shape == (0,) and empty.occupancy.shape == (0, *OCC)
    assert make("one_stage").predict(levels).occupancy is None
    with pytest.raises(ValueError, match="shape"):
        make().predict(levels[:, :4])


@pytest.mark.parametrize("precision", ["fp32", "bf16"])
def test_prediction_is_in_eval_mode(precision):
    # In train mode BatchNorm would use batch statistics, so a level's prediction would depend on its batch.
    surrogate = make(precision=precision)
    dataset, levels = toy_dataset(surrogate, n=32)
    surrogate.train(dataset)
    alone = surrogate.predict(levels[:1]).objective
    together = surrogate.predict(levels).objective[:1]
    np.testing.assert_allclose(alone, together, rtol=1e-5, atol=1e-6)


def test_mae_matches_predictions_and_skips_failures():
    surrogate = make()
    levels = random_levels(6, size=8)
    results = toy_results(levels, OCC)
    results[2] = EvaluationResult.failure(error="boom", num_measures=2, occupancy_shape=OCC)
    mae = surrogate.mae(levels, results)
    keep = [0, 1, 3, 4, 5]
    prediction = surrogate.predict(levels[keep])
    truth = [results[i] for i in keep]
    assert mae["objective"] == pytest.approx(np.mean(np.abs(prediction.objective - [r.objective for r in truth])))
    assert mae["measure_1"] == pytest.approx(np.mean(np.abs(prediction.measures[:, 1] - [r.measures[1] for r in truth])))
    assert mae["occupancy"] == pytest.approx(np.mean(np.abs(prediction.occupancy - [r.occupancy for r in truth])))
    assert "occupancy" not in make("one_stage").mae(levels, results)


def test_same_seed_same_training_different_seed_different():
    runs = []
    for seed in (0, 0, 1):
        surrogate = make(seed=seed)
        dataset, levels = toy_dataset(surrogate, n=40)
        runs.append((surrogate.train(dataset), surrogate.predict(levels).objective))
    assert runs[0][0] == runs[1][0]
    assert np.array_equal(runs[0][1], runs[1][1])
    assert runs[0][0] != runs[2][0]


def test_global_rng_is_left_alone():
    torch.manual_seed(123)
    expected = torch.rand(3)
    torch.manual_seed(123)
    surrogate = make()
    dataset, _ = toy_dataset(surrogate, n=20)
    surrogate.train(dataset)
    assert torch.equal(torch.rand(3), expected)


@pytest.mark.parametrize("kind, precision", [("two_stage", "fp32"), ("two_stage", "bf16"), ("one_stage", "fp32")])
def test_resume_trains_exactly_like_an_uninterrupted_run(kind, precision):
    uninterrupted = make(kind, precision=precision)
    dataset, levels = toy_dataset(uninterrupted, n=40)
    uninterrupted.train(dataset)
    state = pickle.loads(pickle.dumps(uninterrupted.state_dict()))
    expected_losses = [uninterrupted.train(dataset) for _ in range(2)]
    expected = uninterrupted.predict(levels)

    resumed = make(kind, seed=7, precision=precision)  # another seed: everything must come from the checkpoint
    resumed.load_state_dict(state)
    assert [resumed.train(dataset) for _ in range(2)] == expected_losses
    got = resumed.predict(levels)
    assert np.array_equal(got.objective, expected.objective)
    assert np.array_equal(got.measures, expected.measures)


def test_loading_a_checkpoint_does_not_change_it():
    # Adam updates its moment buffers in place; if it adopted the checkpoint's tensors, a second
    # surrogate resumed from the same checkpoint would start from a different state.
    original = make()
    dataset, _ = toy_dataset(original, n=20)
    original.train(dataset)
    state = original.state_dict()
    first, second = make(seed=3), make(seed=4)
    first.load_state_dict(state)
    losses = first.train(dataset)
    second.load_state_dict(state)
    assert second.train(dataset) == losses


def test_state_dict_is_a_snapshot_and_checks_kind():
    surrogate = make()
    dataset, _ = toy_dataset(surrogate, n=20)
    state = surrogate.state_dict()
    weights = {k: v.clone() for k, v in state["model"].items()}
    surrogate.train(dataset)
    assert all(torch.equal(weights[k], v) for k, v in state["model"].items())
    with pytest.raises(ValueError, match="two_stage"):
        make("one_stage").load_state_dict(state)


def test_rejects_bad_arguments():
    with pytest.raises(ValueError, match="kind"):
        make("none")
    with pytest.raises(ValueError, match="empty"):
        surrogate = make()
        surrogate.train(surrogate.make_dataset())
    with pytest.raises(ValueError, match="square"):
        Surrogate(kind="one_stage", input_channels=5, input_shape=(8, 16), occupancy_shape=OCC, num_measures=2,
                  config=SurrogateConfig(device="cpu"), seed=0)


def test_every_training_runs_every_epoch_and_says_so():
    surrogate = make(epochs=4)
    dataset, _ = toy_dataset(surrogate)
    assert [surrogate.train(dataset)["epochs"] for _ in range(2)] == [4, 4]


def test_occupancy_sum_measure_is_the_sum_of_the_predicted_occupancy_in_raw_units():
    config = SurrogateConfig(device="cpu", precision="fp32", occupancy_sum_measure="path")
    surrogate = Surrogate(kind="two_stage", input_channels=5, input_shape=(8, 8), occupancy_shape=OCC,
                          num_measures=2, config=config, seed=0, measure_names=["walls", "path"])
    prediction = surrogate.predict(random_levels(4, size=8, seed=1))
    np.testing.assert_allclose(prediction.measures[:, 1], prediction.occupancy.sum(axis=(1, 2)), rtol=1e-5)
    # The other head is untouched: the same weights without the option predict the same first measure.
    plain = Surrogate(kind="two_stage", input_channels=5, input_shape=(8, 8), occupancy_shape=OCC, num_measures=2,
                      config=SurrogateConfig(device="cpu", precision="fp32"), seed=0)
    np.testing.assert_allclose(prediction.measures[:, 0], plain.predict(random_levels(4, size=8, seed=1)).measures[:, 0])


def test_occupancy_sum_measure_trains_the_occupancy_through_the_measure_loss():
    surrogate = Surrogate(kind="two_stage", input_channels=5, input_shape=(8, 8), occupancy_shape=OCC, num_measures=2,
                          config=SurrogateConfig(device="cpu", precision="fp32", epochs=1, occupancy_weight=0.0,
                                                 occupancy_sum_measure="m1"),
                          seed=0, measure_names=["m0", "m1"])
    dataset, _ = toy_dataset(surrogate, n=16)
    before = [p.detach().clone() for p in surrogate.model.occupancy_predictor.parameters()]
    surrogate.train(dataset)
    after = list(surrogate.model.occupancy_predictor.parameters())
    # With no occupancy loss, only the summed measure's loss can move the occupancy predictor.
    assert any(not torch.equal(b, a) for b, a in zip(before, after))


def test_occupancy_sum_measure_must_name_a_measure_of_a_two_stage_model():
    config = SurrogateConfig(device="cpu", occupancy_sum_measure="path")
    with pytest.raises(ValueError, match="not one of the measures"):
        Surrogate(kind="two_stage", input_channels=5, input_shape=(8, 8), occupancy_shape=OCC, num_measures=2,
                  config=config, seed=0, measure_names=["walls", "length"])
    with pytest.raises(ValueError, match="needs the two_stage surrogate"):
        Surrogate(kind="one_stage", input_channels=5, input_shape=(8, 8), occupancy_shape=OCC, num_measures=2,
                  config=config, seed=0, measure_names=["walls", "path"])


def test_architecture_keys_reach_the_network():
    surrogate = make(channels=8)
    assert surrogate.model.occupancy_predictor.net[0].out_channels == 8
    assert [b.conv1.dilation[0] for b in surrogate.model.occupancy_predictor.net[2:-1]] == [1, 1]  # the paper's
    assert make("one_stage", channels=8).model.measure_predictor.features[0].out_channels == 8
