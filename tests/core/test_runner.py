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
                                     "dsage_novel", "dsage_gain", "map_elites", "dr"])
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


@pytest.mark.parametrize("variant, overrides, steps", [
    ("dsage", {}, 2), ("dsage_gain", {}, 2), ("map_elites", {}, 2),
    # Stopped before its first selection: the random levels' work waits in the checkpoint to be predicted.
    ("dsage_gain", {"selection.cost_measure": "steps"}, 1), ("dsage_gain", {"selection.cost_measure": "occupancy"}, 2)])
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


def test_novel_variant_evaluates_the_dsage_picks_minus_those_the_archive_already_beats(monkeypatch):
    import dsage_ray.core.proposers as proposers_module

    calls = []
    original = proposers_module.skip_filled

    def spy(surrogate_archive, picks, ground_truth_archive):
        result = original(surrogate_archive, picks, ground_truth_archive)
        calls.append((np.array(picks), result))
        return result

    # Same seed, same everything up to selection (skipping draws no randomness).
    dsage, novel = make_runner(variant="dsage"), make_runner(variant="dsage_novel")
    for runner in (dsage, novel):
        runner.step()
    monkeypatch.setattr(proposers_module, "skip_filled", spy)
    plain, skipping = dsage.step(), novel.step()
    assert len(calls) == 1  # only the novel run skips
    picks, result = calls[0]
    assert "selection_filled" not in plain and plain["evaluated_this_iteration"] == len(picks)
    assert skipping["evaluated_this_iteration"] == len(result.kept)
    assert skipping["selection_filled"] == result.filled and skipping["selection_fallback"] == result.fallback


def test_novel_variant_falls_back_to_every_pick_when_the_archive_beats_them_all():
    dsage, novel = make_runner(variant="dsage"), make_runner(variant="dsage_novel")
    for runner in (dsage, novel):
        runner.step()
        # An unbeatable elite in every cell (real objectives are <= 1), in both runs alike.
        dims = runner.archive.dims
        cells = np.stack(np.meshgrid(*[np.arange(d) for d in dims], indexing="ij"), -1).reshape(-1, len(dims))
        lows = np.array([b[0] for b in runner.archive.boundaries])
        widths = np.array([b[1] - b[0] for b in runner.archive.boundaries])
        measures = lows + (cells + 0.5) * widths
        runner.archive.add(np.zeros((len(cells), 64)), np.full(len(cells), 10.0), measures,
                           occupancy=np.zeros((len(cells), 8, 8)))
    plain, skipping = dsage.step(), novel.step()
    assert skipping["selection_fallback"] == 1.0
    assert skipping["selection_filled"] == skipping["evaluated_this_iteration"] == plain["evaluated_this_iteration"]


def test_skip_filled_needs_a_surrogate():
    from dsage_ray.config import ConfigError

    with pytest.raises(ConfigError, match="selection.skip_filled"):
        RunConfig.build({**SMALL, "variant": "map_elites", "selection.skip_filled": True})


@pytest.mark.parametrize("cost_measure", ["", "num_walls", "steps", "occupancy"])
def test_gain_variant_scores_the_picks_by_the_errors_of_the_picks_before(monkeypatch, cost_measure):
    import dsage_ray.core.proposers as proposers_module

    calls = []
    original = proposers_module.best_per_block

    def spy(archive, gains, **kwargs):
        result = original(archive, gains, **kwargs)
        calls.append((gains[result.positions], result))
        return result

    monkeypatch.setattr(proposers_module, "best_per_block", spy)
    runner = make_runner(variant="dsage_gain", **{"selection.min_gain": 0.3, "selection.cost_measure": cost_measure})
    random = runner.step()
    # Nothing was predicted for the random levels: the first selection has the trained surrogate predict them,
    # and starts from those errors (and, with a work count, from their real costs).
    unpredicted = runner.proposer.unpredicted["positions"]
    assert len(unpredicted) == random["evals"] - random.get("failed_evals", 0) and not len(runner.proposer.pick_errors)
    first = runner.step()
    ((_, cold),) = calls
    assert first["evaluated_this_iteration"] == len(cold.indices) and "selection_expected_gain" in first
    assert not len(runner.proposer.unpredicted["positions"])
    errors = len(runner.proposer.pick_errors)
    assert errors == len(unpredicted) + first["evaluated_this_iteration"] - first.get("failed_evals", 0)
    np.testing.assert_array_equal(runner.proposer.pick_errors.actual[:len(unpredicted), 0],
                                  runner.proposer.dataset.objective[unpredicted])
    second = runner.step()
    (_, (chosen_gains, chosen)) = calls
    assert second["evaluated_this_iteration"] == len(chosen.indices)
    assert second["selection_dropped"] == chosen.dropped and second["selection_fallback"] == chosen.fallback
    assert chosen.fallback or chosen_gains.min() >= 0.3
    if not cost_measure:  # every evaluation costs the same: the gain per cost is the gain
        assert second["selection_expected_gain"] == pytest.approx(chosen_gains.sum())
        assert second["selection_relative_cost"] == 1.0
    else:
        assert second["selection_relative_cost"] > 0 and second["selection_expected_gain"] >= 0
    # A work count is recorded per evaluated pick, as the domain counted it; a measure needs none.
    work = runner.proposer.pick_errors.work
    if cost_measure in ("steps", "occupancy"):
        assert np.isfinite(work).all() and work.min() >= 0 and len(set(work.tolist())) > 1
    else:
        assert np.isnan(work).all()


def test_prefer_new_cells_spends_no_pick_on_a_filled_cell_while_its_block_has_an_empty_one(monkeypatch):
    import dsage_ray.core.proposers as proposers_module
    from dsage_ray.qd.selection import block_ids, gather_elites

    block = np.array((4, 2))
    runner = make_runner(**{"selection.prefer_new_cells": True, "selection.block": tuple(block)})
    runner.step()  # the random first levels fill some cells of the ground truth
    truth, domain = runner.archive, runner.proposer.domain
    # A surrogate archive with an elite in every cell of every block the ground truth has a level in: each such
    # block then holds filled and (unless the truth fills it all) empty cells.
    cells = {tuple(corner + offset) for corner in truth.int_to_grid_index(truth.data("index")) // block * block
             for offset in np.ndindex(*block)}
    cells = np.array(sorted(cells))
    lower, upper = np.asarray(truth.lower_bounds), np.asarray(truth.upper_bounds)
    measures = lower + (cells + 0.5) * (upper - lower) / np.asarray(truth.dims)
    surrogate_archive = proposers_module.domain_archive(domain, with_occupancy=False, seed=0)
    surrogate_archive.add(domain.random_solutions(len(cells), np.random.default_rng(0)), np.full(len(cells), 0.5),
                          measures)
    monkeypatch.setattr(runner.proposer, "_exploit", lambda: surrogate_archive)
    checked = []
    original = proposers_module.select_solutions

    def spy(archive, **kwargs):
        picks = original(archive, **kwargs)
        assert archive is surrogate_archive and kwargs["new_cells"] is truth
        indices = np.sort(archive.data("index"))
        held = truth.retrieve(gather_elites(archive, indices)["measures"])[0]
        blocks = block_ids(archive, indices, kwargs["block"])
        for pick in np.searchsorted(indices, picks):
            in_block = blocks == blocks[pick]
            checked.append(bool(held[in_block].any() and not held[in_block].all()))
            assert not held[pick] or held[in_block].all()
        return picks

    monkeypatch.setattr(proposers_module, "select_solutions", spy)
    runner.step()
    # Every block got its pick, and blocks holding both kinds of cell, where the preference decides, came up.
    assert len(checked) == len(set(block_ids(surrogate_archive, surrogate_archive.data("index"), block)))
    assert any(checked)


def test_elite_mutants_are_evaluated_beside_the_picks_and_are_mutants_of_the_best_real_elites(monkeypatch):
    import dsage_ray.core.proposers as proposers_module
    from dsage_ray.qd.mutants import best_elites

    runner = make_runner(**{"selection.elite_mutants": 7, "selection.elite_share": 0.1, "qd.mutation_cells": 3,
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


@pytest.mark.parametrize("cost_measure", ["steps", "occupancy"])
def test_a_work_count_is_read_from_each_result_and_predicted_only_where_the_surrogate_can(cost_measure):
    from dsage_ray.core.proposers import EvaluatedBatch, Proposal
    from dsage_ray.surrogate.models import encode_solutions

    runner = make_runner(variant="dsage_gain", **{"selection.cost_measure": cost_measure})
    runner.step()
    runner.step()
    proposer, domain = runner.proposer, runner.proposer.domain
    solutions = domain.random_solutions(6, np.random.default_rng(0))
    results = [domain.evaluate(solution, seed=k) for k, solution in enumerate(solutions)]
    batch = EvaluatedBatch.collect(Proposal(solutions), results, domain=domain, outer_iteration=2)
    recorded = proposer.work_count.recorded(batch)
    predicted = proposer.work_count.predicted(proposer.surrogate, solutions)
    if cost_measure == "steps":
        np.testing.assert_array_equal(recorded, [domain.work_counts(r)["steps"] for r in results])
        assert predicted is None  # the selection then takes what the nearest recent picks recorded
    else:
        np.testing.assert_allclose(recorded, [r.occupancy.sum() for r in results], rtol=1e-6)
        own = proposer.surrogate.predict(encode_solutions(domain, solutions)).occupancy
        np.testing.assert_allclose(predicted, own.reshape(6, -1).sum(axis=1), rtol=1e-6)


@pytest.mark.parametrize("overrides, key", [
    ({"variant": "map_elites", "selection.expected_gain": True}, "selection.expected_gain"),
    ({"variant": "dsage_gain", "selection.method": "random"}, "selection.expected_gain"),
    ({"variant": "dsage_gain", "selection.min_gain": -0.1}, "selection.min_gain"),
    ({"variant": "dsage_gain", "selection.gain_window": 0}, "selection.gain_window"),
    ({"variant": "dsage_gain", "selection.gain_neighbours": 0}, "selection.gain_neighbours"),
    ({"variant": "dsage_gain", "selection.cost_offset": 0.0}, "selection.cost_offset"),
    ({"variant": "dsage_gain", "selection.cost_measure": "jumps"}, "selection.cost_measure"),
    ({"variant": "map_elites", "selection.prefer_new_cells": True}, "selection.prefer_new_cells"),
    ({"variant": "dsage_rsample", "selection.prefer_new_cells": True}, "selection.prefer_new_cells"),
    ({"variant": "dsage_gain", "selection.prefer_new_cells": True}, "selection.prefer_new_cells"),
    ({"variant": "dsage_gain", "selection.cost_measure": "occupancy", "surrogate.kind": "one_stage"},
     "selection.cost_measure"),
    ({"variant": "map_elites", "selection.elite_mutants": 10}, "selection.elite_mutants"),
    ({"variant": "dsage", "selection.elite_mutants": -1}, "selection.elite_mutants"),
    ({"variant": "dsage", "selection.elite_mutants": 10, "qd.emitter": "random"}, "selection.elite_mutants"),
    ({"variant": "dsage", "selection.elite_share": 0.0}, "selection.elite_share"),
    ({"variant": "dsage", "selection.elite_share": 1.5}, "selection.elite_share"),
])
def test_expected_gain_config_is_checked(overrides, key):
    from dsage_ray.config import ConfigError

    with pytest.raises(ConfigError, match=key):
        RunConfig.build({**SMALL, **overrides})


def test_a_cost_measure_is_checked_only_where_expected_gain_reads_it():
    from dsage_ray.config import ConfigError

    # A cost model names the path length; an audit may search other measures.
    other_measures = {**SMALL, "maze.measures": ["num_walls", "optimal_path_length"],
                      "selection.cost_measure": "mean_path_length"}
    RunConfig.build({**other_measures, "variant": "dsage"})
    with pytest.raises(ConfigError, match="selection.cost_measure: 'mean_path_length' is neither one of the measures"):
        RunConfig.build({**other_measures, "variant": "dsage_gain"})


def test_a_cost_measure_the_domain_lacks_is_refused_by_name():
    from dsage_ray.config import ConfigError

    # The config's own Maze section has a path length; the domain passed in does not.
    with pytest.raises(ConfigError, match="selection.cost_measure: 'mean_path_length' is neither one of the domain's measures"):
        make_runner(variant="dsage_gain", **{"selection.cost_measure": "mean_path_length"})
    make_runner(variant="dsage", **{"selection.cost_measure": "mean_path_length"})  # read only by dsage_gain


def _screening_runner(**overrides) -> DSAGE:
    from tests.fakes import ScreeningBitmapDomain

    return DSAGE(config=RunConfig.build({**SMALL, "budget": 160, "selection.screen_episodes": 1, **overrides}),
                 domain=ScreeningBitmapDomain())


def test_with_an_exact_screen_every_screened_pick_fills_a_new_cell_and_the_screen_is_timed():
    runner = _screening_runner()
    history = runner.run()
    screened = [h for h in history[1:] if not h["selection_screen_fallback"]]
    assert screened and runner.domain.screened == sum(h["selection_screened"] for h in history[1:])
    assert all(h["new_cell_share"] == 1.0 for h in screened)
    assert all(0 < h["time_screen"] <= h["time_select"] for h in history[1:])
    # Without the screen the same search spends picks on cells it already holds.
    plain = make_runner(budget=160)
    assert min(h["new_cell_share"] for h in plain.run()[1:]) < 1.0


def test_a_screened_run_resumes_exactly():
    reference = _screening_runner()
    reference.run()
    resumed = resumed_after(_screening_runner, 2)
    assert archive_snapshot(resumed.archive) == archive_snapshot(reference.archive)


def test_screened_map_elites_evaluates_only_mutants_whose_screen_fills_a_new_cell_after_its_random_start():
    runner = _screening_runner(variant="map_elites")
    history = runner.run()
    assert runner.evals == 160
    start = RunConfig.build(SMALL).qd.initial_random_batches
    assert all("selection_screened" not in h for h in history[:start])  # the random start-up is not screened
    screened = [h for h in history[start:] if not h["selection_screen_fallback"]]
    assert screened and runner.domain.screened == sum(h["selection_screened"] for h in history[start:])
    assert all(h["new_cell_share"] == 1.0 for h in screened)
    assert all(h["selection_screened"] == 4 * 20 for h in history[start:])  # screen_pool × the batch of 2 × 10
    plain = make_runner(variant="map_elites", budget=160)
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
    errors = reference.proposer.screen_errors
    # Every evaluated level was screened (none failed): each is one recorded error, and an exact screen errs by 0.
    screened = [h for h in history if "selection_screened" in h]
    assert len(errors) == min(sum(h["evaluated_this_iteration"] for h in screened), errors.window) > 0
    np.testing.assert_array_equal(errors.actual, errors.predicted)
    assert all(h["new_cell_share"] == 1.0 for h in screened if not h["selection_screen_fallback"])
    assert all(h["selection_screen_expected_new"] <= h["evaluated_this_iteration"] for h in screened)
    resumed = resumed_after(lambda: _screening_runner(**ranked), 5)
    assert archive_snapshot(resumed.archive) == archive_snapshot(reference.archive)
    np.testing.assert_array_equal(resumed.proposer.screen_errors.predicted, errors.predicted)


@pytest.mark.parametrize("overrides, needle", [
    ({"selection.screen_episodes": -1}, "selection.screen_episodes: must be >= 0"),
    ({"selection.screen_gain": True}, "selection.screen_gain: ranks screened candidates; set selection.screen_episodes"),
    ({"selection.screen_episodes": 1, "variant": "dr"}, "selection.screen_episodes: screens a surrogate's picks, or "
                                                        "MAP-Elites' mutants; qd.emitter 'random'"),
    ({"selection.screen_episodes": 1, "selection.screen_pool": 0.5}, "selection.screen_pool: must be >= 1")])
def test_screen_config_is_checked(overrides, needle):
    with pytest.raises(ValueError, match=needle):
        RunConfig.build({**SMALL, **overrides})


def test_a_domain_that_cannot_screen_is_refused_by_name():
    from dsage_ray.config import ConfigError

    with pytest.raises(ConfigError, match="selection.screen_episodes: the 'bitmap' domain cannot screen"):
        make_runner(**{"selection.screen_episodes": 2})
