"""Held-out surrogate accuracy: extra evaluations outside the budget, scored every outer iteration."""

import pickle

import numpy as np
import pytest
from scipy import stats

from dsage_ray.config import RunConfig
from dsage_ray.core.runner import DSAGE
from dsage_ray.domains.maze.plugin import MazeConfig
from tests.core.test_runner import archive_snapshot, make_runner
from tests.fakes import SMALL_RUN, BitmapDomain

HOLDOUT = 12
HEADS = ("objective", "num_walls", "top_walls")


def holdout_history(runner):
    return [{k: v for k, v in h.items() if k.startswith("holdout_")} for h in runner.history]


def test_holdout_metrics_every_trained_iteration_outside_the_budget():
    runner = make_runner(**{"experimental.holdout_levels": HOLDOUT})
    first = runner.step()
    assert first["holdout_evals"] == HOLDOUT and first["evals"] == SMALL_RUN["n_rand"]
    assert not any(k.startswith(("holdout_mae", "holdout_spearman")) for k in first)  # nothing trained yet
    assert len(runner.dataset) == SMALL_RUN["n_rand"]
    second = runner.step()
    for head in HEADS:
        assert 0 <= second[f"holdout_mae_{head}"] and -1 <= second[f"holdout_spearman_{head}"] <= 1
        assert f"mae_{head}" in second  # the selected batch's error stays beside it
    assert "holdout_mae_occupancy" in second and "holdout_spearman_occupancy" not in second

    # The figures are the surrogate's own error on the stored held-out levels.
    held = runner.holdout
    encoded = runner.domain.encode(held["solutions"])
    prediction = runner.surrogate.predict(encoded)
    true_walls = np.array([r.measures[0] for r in held["results"]])
    assert second["holdout_mae_num_walls"] == pytest.approx(np.abs(prediction.measures[:, 0] - true_walls).mean())
    assert second["holdout_spearman_num_walls"] == pytest.approx(
        stats.spearmanr(prediction.measures[:, 0], true_walls).statistic)


def test_held_out_levels_never_change_the_search():
    plain = make_runner()
    plain.run()
    measured = make_runner(**{"experimental.holdout_levels": HOLDOUT})
    measured.run()
    assert archive_snapshot(measured.archive) == archive_snapshot(plain.archive)
    assert [h["qd_score"] for h in measured.history] == [h["qd_score"] for h in plain.history]
    assert measured.evals == plain.evals == SMALL_RUN["budget"]
    assert len(measured.dataset) == len(plain.dataset) == SMALL_RUN["budget"]
    archived = {bytes(s) for s in measured.archive.data("solution").astype(np.int8)}
    assert not archived & {bytes(s) for s in measured.holdout["solutions"].astype(np.int8)}
    assert measured.history[-1]["holdout_evals"] == HOLDOUT and plain.history[-1]["holdout_evals"] == 0


def test_holdout_metrics_are_exact_across_checkpoint_resume_and_not_re_evaluated():
    overrides = {"experimental.holdout_levels": HOLDOUT}
    reference = make_runner(**overrides)
    reference.run()
    assert any("holdout_spearman_num_walls" in h for h in reference.history)

    interrupted = make_runner(**overrides)
    interrupted.step()
    interrupted.step()
    state = pickle.loads(pickle.dumps(interrupted.state_dict()))

    domain = BitmapDomain()
    resumed = DSAGE(config=RunConfig.build({**SMALL_RUN, **overrides}), domain=domain)
    resumed.load_state_dict(state)
    resumed.run()
    assert holdout_history(resumed) == holdout_history(reference)
    assert domain.calls == SMALL_RUN["budget"] - interrupted.evals  # the held-out set came from the checkpoint
    assert resumed.holdout_evals == HOLDOUT


def test_held_out_set_depends_on_the_seed_only():
    a, b, c = (make_runner(**{"experimental.holdout_levels": HOLDOUT, "seed": s}) for s in (0, 0, 1))
    for runner in (a, b, c):
        runner.step()
    np.testing.assert_array_equal(a.holdout["solutions"], b.holdout["solutions"])
    assert not np.array_equal(a.holdout["solutions"], c.holdout["solutions"])


class ValidOnlyDomain(BitmapDomain):
    """Marks where held-out levels come from: a domain that can draw valid levels says so."""

    def random_valid_solutions(self, n, rng):
        solutions = self.random_solutions(n, rng)
        solutions[:, :8] = 0  # an open first row
        return solutions


def test_domains_with_valid_levels_supply_the_held_out_set_and_failures_are_left_out():
    config = RunConfig.build({**SMALL_RUN, "experimental.holdout_levels": HOLDOUT})
    runner = DSAGE(config=config, domain=ValidOnlyDomain())
    runner.step()
    assert np.all(runner.holdout["solutions"][:, :8] == 0)

    broken = BitmapDomain(fail_on=tuple(range(0, 65)), fail_once=False)  # every evaluation fails
    runner = DSAGE(config=config, domain=broken)
    runner.proposer.holdout.evaluate(runner.evaluator)
    assert runner.holdout["results"] == [] and runner.holdout_evals == HOLDOUT
    assert runner.failures == []  # held-out failures are not budget failures


def test_baselines_hold_nothing_out():
    runner = make_runner(variant="map_elites", **{"experimental.holdout_levels": HOLDOUT})
    metrics = runner.step()
    assert metrics["holdout_evals"] == 0 and runner.holdout is None


def test_maze_held_out_levels_are_valid_and_seeded():
    from dsage_ray.domains.maze.domain import MazeDomain

    domain = MazeDomain(config=MazeConfig())
    solutions = domain.random_valid_solutions(20, np.random.default_rng(3))
    assert solutions.shape == (20, 256) and solutions.dtype == domain.solution_dtype
    assert all(domain.level(s).valid for s in solutions)
    np.testing.assert_array_equal(solutions, domain.random_valid_solutions(20, np.random.default_rng(3)))
    assert len({int(s.sum()) for s in solutions}) > 5  # a spread of wall counts, not one density


def test_bad_holdout_count_is_one_config_error():
    from dsage_ray.config import ConfigError

    with pytest.raises(ConfigError, match="experimental.holdout_levels"):
        RunConfig.build({**SMALL_RUN, "experimental.holdout_levels": -1})


def test_a_batch_whose_every_evaluation_fails_stops_the_run_with_the_evaluations_error():
    from dsage_ray.core.runner import EvaluationsFailed

    broken = BitmapDomain(fail_on=tuple(range(0, 65)), fail_once=False)  # every evaluation fails
    runner = DSAGE(config=RunConfig.build(SMALL_RUN), domain=broken)
    with pytest.raises(EvaluationsFailed, match="every evaluation of outer iteration 0 failed") as failure:
        runner.step()
    assert "injected failure for a level with" in str(failure.value)  # the evaluations' own error
    assert runner.evals == 0 and len(runner.failures) == RunConfig.build(SMALL_RUN).n_rand
