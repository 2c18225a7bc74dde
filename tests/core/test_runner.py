import pickle

import numpy as np
import pytest

from dsage_ray.config import RunConfig
from dsage_ray.core.runner import DSAGE
from tests.fakes import SMALL_RUN, BitmapDomain

SMALL = SMALL_RUN


def make_runner(**overrides) -> DSAGE:
    config = RunConfig.build({**SMALL, **overrides})
    return DSAGE(config=config, domain=BitmapDomain())


def archive_snapshot(archive) -> tuple:
    data = archive.data()
    order = np.argsort(data["index"])
    return (data["index"][order].tolist(), data["objective"][order].tolist(), data["solution"][order].tolist())


@pytest.mark.parametrize("variant", ["dsage", "dsage_only_anc", "dsage_only_down", "dsage_basic", "dsage_rsample",
                                     "map_elites", "dr"])
def test_every_variant_spends_exactly_the_budget(variant):
    runner = make_runner(variant=variant)
    history = runner.run()
    assert runner.evals == SMALL["budget"]
    assert history[-1]["evals"] == SMALL["budget"]
    assert [h["evals"] for h in history] == sorted(h["evals"] for h in history)
    assert history[-1]["qd_score"] > 0
    assert 0 < history[-1]["coverage"] <= 1
    assert len(runner.archive) == history[-1]["archive_size"]


def test_first_iteration_evaluates_n_rand_random_solutions():
    runner = make_runner()
    metrics = runner.step()
    assert metrics["evals"] == SMALL["n_rand"]
    assert len(runner.dataset) == SMALL["n_rand"]


def test_surrogate_iterations_report_losses_errors_and_phase_times():
    runner = make_runner()
    runner.step()
    metrics = runner.step()
    for key in ("surrogate_loss", "mae_objective", "mae_num_walls", "mae_occupancy", "time_train", "time_exploit",
                "time_select", "time_evaluate", "new_cell_share"):
        assert key in metrics, key
    predicted, true = runner.last_predictions
    assert predicted.shape == true.shape


def test_one_stage_surrogate_has_no_occupancy_error():
    runner = make_runner(variant="dsage_basic")
    runner.step()
    assert "mae_occupancy" not in runner.step()


def test_same_seed_same_run_and_different_seed_differs():
    a, b, c = make_runner(), make_runner(), make_runner(seed=1)
    for runner in (a, b, c):
        runner.run()
    assert archive_snapshot(a.archive) == archive_snapshot(b.archive)
    assert archive_snapshot(a.archive) != archive_snapshot(c.archive)


@pytest.mark.parametrize("variant", ["dsage", "map_elites"])
def test_resumed_run_continues_exactly(variant):
    reference = make_runner(variant=variant)
    reference.run()

    interrupted = make_runner(variant=variant)
    interrupted.step()
    interrupted.step()
    state = pickle.loads(pickle.dumps(interrupted.state_dict()))
    del interrupted

    resumed = make_runner(variant=variant)
    resumed.load_state_dict(state)
    resumed.run()
    assert archive_snapshot(resumed.archive) == archive_snapshot(reference.archive)
    assert [h["qd_score"] for h in resumed.history] == [h["qd_score"] for h in reference.history]


def test_state_from_another_config_is_refused():
    state = make_runner().state_dict()
    with pytest.raises(ValueError, match="different config"):
        make_runner(seed=5).load_state_dict(state)


def test_failed_evaluation_is_retried_once_then_recorded():
    config = RunConfig.build({**SMALL, "variant": "dr"})
    batch = config.qd.num_emitters * config.qd.batch_size
    flaky = BitmapDomain(fail_on=tuple(range(0, 65)), fail_once=True)  # every level fails once
    runner = DSAGE(config=config, domain=flaky)
    runner.step()
    assert runner.failures == []
    assert flaky.calls == 2 * batch  # each evaluation ran twice, none more
    assert len(runner.archive) > 0

    broken = BitmapDomain(fail_on=tuple(range(0, 65)), fail_once=False)
    runner = DSAGE(config=config, domain=broken)
    metrics = runner.step()
    assert len(runner.failures) == batch and "injected failure" in runner.failures[0]["error"]
    assert metrics["evals"] == batch and metrics["failed_evals"] == batch and len(runner.archive) == 0
    assert [f["eval_index"] for f in runner.failures] == list(range(batch))


def test_write_outputs(tmp_path):
    runner = make_runner()
    runner.run()
    runner.write_outputs(tmp_path)
    import json

    metrics = json.loads((tmp_path / "metrics.json").read_text())
    assert metrics[-1]["evals"] == SMALL["budget"] and "qd_score" in metrics[0] and "coverage" in metrics[0]
    header = (tmp_path / "archive.csv").read_text().splitlines()[0]
    assert "objective" in header and "measures_0" in header
    assert (tmp_path / "heatmap.png").read_bytes()[:4] == b"\x89PNG"
    assert list((tmp_path / "elites").glob("elite_*.png"))
    assert not [p for p in tmp_path.rglob("*.tmp")]


@pytest.mark.parametrize("variant", ["map_elites", "dr"])
def test_baseline_survives_batches_with_failed_evaluations(variant):
    config = RunConfig.build({**SMALL, "variant": variant, "budget": 100})
    domain = BitmapDomain(fail_on=tuple(range(28, 36)), fail_once=False)  # common wall counts
    runner = DSAGE(config=config, domain=domain)
    history = runner.run()
    assert runner.failures, "the fault injection should have hit some levels"
    assert history[-1]["evals"] == 100
    assert len(runner.archive) > 0
    assert {int(np.sum(f["solution"])) for f in runner.failures} <= set(range(28, 36))
