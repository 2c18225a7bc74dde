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


def resumed_after(build, steps: int) -> DSAGE:
    """A run of ``build()`` stopped after ``steps`` outer iterations, its state pickled, resumed in a fresh
    ``build()`` and run to the end."""
    interrupted = build()
    for _ in range(steps):
        interrupted.step()
    state = pickle.loads(pickle.dumps(interrupted.state_dict()))
    resumed = build()
    resumed.load_state_dict(state)
    resumed.run()
    return resumed


@pytest.mark.parametrize("variant, overrides, steps", [("dsage", {}, 2), ("dsage", {}, 1), ("map_elites", {}, 2)])
def test_resumed_run_continues_exactly(variant, overrides, steps):
    reference = make_runner(variant=variant, **overrides)
    reference.run()

    resumed = resumed_after(lambda: make_runner(variant=variant, **overrides), steps)
    assert archive_snapshot(resumed.archive) == archive_snapshot(reference.archive)
    assert [h["qd_score"] for h in resumed.history] == [h["qd_score"] for h in reference.history]


def test_state_from_another_config_is_refused():
    state = make_runner().state_dict()
    with pytest.raises(ValueError, match="different config: seed = 0, not 5$"):
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

    # A batch that fails entirely stops the run with the evaluations' own error; each failure is recorded.
    from dsage_ray.core.runner import EvaluationsFailed

    broken = BitmapDomain(fail_on=tuple(range(0, 65)), fail_once=False)
    runner = DSAGE(config=config, domain=broken)
    with pytest.raises(EvaluationsFailed, match="injected failure"):
        runner.step()
    assert len(runner.failures) == batch and "injected failure" in runner.failures[0]["error"]
    assert runner.evals == 0 and len(runner.archive) == 0
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


def test_elite_mutants_are_evaluated_beside_the_picks_and_are_mutants_of_the_best_real_elites(monkeypatch):
    import dsage_ray.core.proposers as proposers_module
    from dsage_ray.qd.mutants import best_elites

    runner = make_runner(**{"selection.elite_mutants": 7, "experimental.elite_share": 0.1, "qd.mutation_cells": 3,
                            "budget": 400})
    first = runner.step()
    assert "selection_elite_mutants" not in first  # the random first batch has no elites to mutate
    parents_seen = []
    original = proposers_module.elite_mutants

    def spy(archive, **kwargs):
        assert archive is runner.archive
        parents_seen.append(archive.data("solution")[best_elites(archive, share=kwargs["share"])].copy())
        return original(archive, **kwargs)

    monkeypatch.setattr(proposers_module, "elite_mutants", spy)
    proposal = runner.proposer.propose(outer_iteration=1)
    mutants = proposal.solutions[-7:]
    assert proposal.metrics["selection_elite_mutants"] == 7
    distance = np.abs(mutants[:, None, :].astype(int) - parents_seen[0][None].astype(int)).sum(axis=2).min(axis=1)
    assert 0 < distance.max() <= 3
    # Without the key the same proposal holds only the picks: the mutants come on top of them.
    plain = make_runner(budget=400)
    plain.step()
    assert len(plain.proposer.propose(outer_iteration=1).solutions) == len(proposal.solutions) - 7


def test_a_run_with_elite_mutants_spends_its_budget_and_resumes_exactly():
    overrides = {"selection.elite_mutants": 5, "budget": 120}
    reference = make_runner(**overrides)
    history = reference.run()
    assert reference.evals == 120 and history[-1]["evals"] == 120
    assert [h.get("selection_elite_mutants") for h in history] == [None] + [5.0] * (len(history) - 1)
    resumed = resumed_after(lambda: make_runner(**overrides), 2)
    assert archive_snapshot(resumed.archive) == archive_snapshot(reference.archive)


@pytest.mark.parametrize("overrides, key", [
    ({"experimental.gain_window": 0}, "experimental.gain_window"),
    ({"experimental.gain_neighbours": 0}, "experimental.gain_neighbours"),
    ({"selection.cost_offset": 74}, "selection.cost_offset: this key was removed"),
    ({"variant": "map_elites", "selection.elite_mutants": 10}, "selection.elite_mutants"),
    ({"variant": "dsage", "selection.elite_mutants": -1}, "selection.elite_mutants"),
    ({"variant": "dsage", "selection.elite_mutants": 10, "qd.emitter": "random"}, "selection.elite_mutants"),
    ({"variant": "dsage", "experimental.elite_share": 0.0}, "experimental.elite_share"),
    ({"variant": "dsage", "experimental.elite_share": 1.5}, "experimental.elite_share"),
    ({"variant": "dsage", "experimental.mutant_sigma": -0.1}, "experimental.mutant_sigma: must be >= 0"),
    ({"variant": "dsage", "experimental.mutant_sigma": 0.01}, "experimental.mutant_sigma: is the Gaussian step"),
])
def test_selection_config_is_checked(overrides, key):
    from dsage_ray.config import ConfigError

    with pytest.raises(ConfigError, match=key):
        RunConfig.build({**SMALL, **overrides})


#: The screened runs' budget: 60 evaluations after the 40 random ones hold about ten screened iterations (the
#: rest fall back), and the later iterations, with a larger archive to screen against, cost the most.
SCREENED_BUDGET = 100


def _screening_runner(**overrides) -> DSAGE:
    from tests.fakes import ScreeningBitmapDomain

    config = RunConfig.build({**SMALL, "budget": SCREENED_BUDGET, "selection.screen_episodes": 1, **overrides})
    return DSAGE(config=config, domain=ScreeningBitmapDomain())


@pytest.fixture(scope="module")
def screened_run() -> tuple[DSAGE, list[dict]]:
    """One screened DSAGE run to its budget and its history, read by the tests of what it did and of its resume."""
    runner = _screening_runner()
    return runner, runner.run()


def test_with_an_exact_screen_every_screened_pick_fills_a_new_cell_and_the_screen_is_timed(screened_run):
    runner, history = screened_run
    screened = [h for h in history[1:] if not h["selection_screen_fallback"]]
    assert screened and runner.domain.screened == sum(h["selection_screened"] for h in history[1:])
    assert all(h["new_cell_share"] == 1.0 for h in screened)
    assert all(0 < h["time_screen"] <= h["time_select"] for h in history[1:])
    # Without the screen the same search spends picks on cells it already holds.
    plain = make_runner(budget=SCREENED_BUDGET)
    assert min(h["new_cell_share"] for h in plain.run()[1:]) < 1.0


def test_a_screened_run_resumes_exactly(screened_run):
    reference, _ = screened_run
    resumed = resumed_after(_screening_runner, 2)
    assert archive_snapshot(resumed.archive) == archive_snapshot(reference.archive)


def test_screened_map_elites_evaluates_only_mutants_whose_screen_fills_a_new_cell_after_its_random_start():
    runner = _screening_runner(variant="map_elites")
    history = runner.run()
    assert runner.evals == SCREENED_BUDGET
    from dsage_ray.qd.optimizer import MAP_ELITES_RANDOM_BATCHES as start

    assert all("selection_screened" not in h for h in history[:start])  # the random start-up is not screened
    screened = [h for h in history[start:] if not h["selection_screen_fallback"]]
    assert screened and runner.domain.screened == sum(h["selection_screened"] for h in history[start:])
    assert all(h["new_cell_share"] == 1.0 for h in screened)
    assert all(h["selection_screened"] == 4 * 20 for h in history[start:])  # screen_pool × the batch of 2 × 10
    plain = make_runner(variant="map_elites", budget=SCREENED_BUDGET)
    assert min(h["new_cell_share"] for h in plain.run()[start:]) < 1.0


def test_screened_map_elites_resumes_exactly():
    reference = _screening_runner(variant="map_elites")
    reference.run()
    resumed = resumed_after(lambda: _screening_runner(variant="map_elites"), 5)
    assert archive_snapshot(resumed.archive) == archive_snapshot(reference.archive)


@pytest.mark.parametrize("variant", ["dsage", "map_elites"])
def test_ranked_by_the_screens_errors_a_run_records_them_fills_new_cells_and_resumes_exactly(variant):
    ranked = {"variant": variant, "selection.screen_gain": True}
    reference = _screening_runner(**ranked)
    history = reference.run()
    errors = reference.proposer.screen.errors
    # Every evaluated level was screened (none failed): each is one recorded error, and an exact screen errs by 0.
    screened = [h for h in history if "selection_screened" in h]
    assert len(errors) == min(sum(h["evaluated_this_iteration"] for h in screened), errors.window) > 0
    np.testing.assert_array_equal(errors.actual, errors.predicted)
    assert all(h["new_cell_share"] == 1.0 for h in screened if not h["selection_screen_fallback"])
    assert all(h["selection_screen_expected_new"] <= h["evaluated_this_iteration"] for h in screened)
    resumed = resumed_after(lambda: _screening_runner(**ranked), 5)
    assert archive_snapshot(resumed.archive) == archive_snapshot(reference.archive)
    np.testing.assert_array_equal(resumed.proposer.screen.errors.predicted, errors.predicted)


@pytest.mark.parametrize("overrides, needle", [
    ({"selection.screen_episodes": -1}, "selection.screen_episodes: must be >= 0"),
    ({"selection.screen_gain": True}, "selection.screen_gain: ranks screened candidates; set selection.screen_episodes"),
    ({"selection.screen_episodes": 1, "variant": "dr"}, "selection.screen_episodes: screens a surrogate's picks, or "
                                                        "MAP-Elites' mutants; qd.emitter 'random'"),
    ({"selection.screen_episodes": 1, "experimental.screen_pool": 0.5}, "experimental.screen_pool: must be >= 1")])
def test_screen_config_is_checked(overrides, needle):
    with pytest.raises(ValueError, match=needle):
        RunConfig.build({**SMALL, **overrides})


def test_a_domain_that_cannot_screen_is_refused_by_name():
    from dsage_ray.config import ConfigError

    with pytest.raises(ConfigError, match="selection.screen_episodes: the 'bitmap' domain cannot screen"):
        make_runner(**{"selection.screen_episodes": 2})


@pytest.mark.parametrize("model, screen_gain, expected", [
    (("num_walls", 2.0), True, (0, 2.0)), (("num_walls", 2.0), False, None), (("jumps", 2.0), True, None),
    (None, True, None)])
def test_a_ranked_screen_prices_levels_by_the_domains_cost_model_where_the_run_measures_it(model, screen_gain,
                                                                                            expected):
    from dsage_ray.core.screening import evaluation_cost
    from dsage_ray.qd.gain import EvaluationCost
    from tests.fakes import ScreeningBitmapDomain

    domain = ScreeningBitmapDomain()
    domain.evaluation_cost = model
    config = RunConfig.build({**SMALL, "selection.screen_episodes": 1, "selection.screen_gain": screen_gain})
    assert evaluation_cost(config, domain) == (None if expected is None else EvaluationCost(*expected))
