import pickle

import pytest

from dsage_ray.config import ConfigError, RunConfig
from dsage_ray.core import auto_search
from dsage_ray.core import runner as runner_module
from dsage_ray.core.auto_search import SearchChoice, choose_search, direct_config, pick_allowance
from dsage_ray.core.proposers import DirectQD, SurrogateAssisted
from dsage_ray.core.runner import DSAGE
from tests.core.test_runner import archive_snapshot
from tests.fakes import SMALL_RUN, BitmapDomain

#: Long enough for the direct search to run after the choice (iteration 0: 40 random levels; MAP-Elites: 150 a batch).
AUTO = {**SMALL_RUN, "budget": 200, "search": "auto"}


def make_runner(**overrides) -> DSAGE:
    return DSAGE(config=RunConfig.build({**AUTO, **overrides}), domain=BitmapDomain())


def random_row(seconds=2.0, levels=40):
    return {"time_evaluate": seconds, "evaluated_this_iteration": float(levels)}


def test_the_ratio_is_what_a_pick_cost_surrogate_and_evaluation_included_over_a_random_level():
    choice = choose_search([random_row(2.0, 40)], surrogate_seconds=5.0, evaluate_seconds=3.0, evaluated=25,
                           direct_variant="map_elites")
    assert choice.random_level_seconds == pytest.approx(0.05)
    assert choice.surrogate_level_seconds == pytest.approx(8.0 / 25)
    assert choice.cost_ratio == pytest.approx(0.32 / 0.05)
    assert choice.direct is (choice.cost_ratio > auto_search.BREAK_EVEN_COST_RATIO)
    assert choice.outer_iteration == 1


def test_the_picks_may_take_what_keeps_them_under_the_break_even():
    allowance = pick_allowance([random_row(2.0, 40)], surrogate_seconds=1.0, picks=25)
    assert allowance == pytest.approx(auto_search.BREAK_EVEN_COST_RATIO * 0.05 * 25 - 1.0)
    # Evaluated in exactly that time, the picks cost the break-even.
    at = choose_search([random_row(2.0, 40)], surrogate_seconds=1.0, evaluate_seconds=allowance, evaluated=25,
                       direct_variant="map_elites")
    assert at.cost_ratio == pytest.approx(auto_search.BREAK_EVEN_COST_RATIO)


@pytest.mark.parametrize("evaluate_seconds, direct", [(0.5, False), (100.0, True)])
def test_the_break_even_decides(evaluate_seconds, direct):
    choice = choose_search([random_row(2.0, 40)], surrogate_seconds=0.5, evaluate_seconds=evaluate_seconds,
                           evaluated=25, direct_variant="cma_me")
    assert choice.direct is direct
    assert ("continuing with cma_me" in choice.reason) is direct
    assert f"{choice.cost_ratio:.2f}×" in choice.reason


def test_a_choice_round_trips_through_its_metrics_and_state():
    choice = choose_search([random_row()], surrogate_seconds=100.0, evaluate_seconds=0.0, evaluated=25,
                           direct_variant="map_elites")
    row = {"outer_iteration": 1.0, **choice.metrics()}
    assert SearchChoice.from_metrics(row, variant="map_elites") == choice
    assert SearchChoice.from_metrics({"outer_iteration": 1.0}, variant="map_elites") is None
    assert SearchChoice.from_state_dict(pickle.loads(pickle.dumps(choice.state_dict()))) == choice


def test_the_direct_config_is_the_domains_direct_variant_over_the_run():
    config = RunConfig.build({**AUTO, "seed": 7, "time_budget": 30.0})
    direct = direct_config(config)
    assert (direct.variant, direct.search, direct.surrogate.kind, direct.qd.emitter) == (
        "map_elites", "fixed", "none", "map_elites")
    assert (direct.budget, direct.seed, direct.time_budget, direct.maze.archive_dims) == (200, 7, 30.0, (16, 8))


@pytest.mark.parametrize("domain, keys", [
    ("maze", {"selection.elite_mutants": 150, "selection.screen_episodes": 1, "selection.screen_gain": True}),
    ("gym", {"selection.elite_mutants": 15, "gym.space": "cartpole"}),
    ("mario", {"preset": "cpu"}),
])
def test_the_direct_search_of_every_domain_is_a_valid_run_without_the_keys_of_a_surrogates_picks(domain, keys):
    config = RunConfig.build({"domain": domain, "search": "auto", **keys})
    config.validate()
    direct = direct_config(config)
    direct.validate()
    assert (direct.surrogate.kind, direct.selection.elite_mutants, direct.selection.screen_episodes) == ("none", 0, 0)
    assert direct.variant == {"maze": "map_elites", "mario": "cma_me", "gym": "cross_entropy"}[domain]


@pytest.mark.parametrize("overrides, message", [
    ({"variant": "map_elites"}, "auto starts as DSAGE"),
    ({"pipeline": True}, "set pipeline = false"),
    ({"surrogate.init": "some/folder"}, "a warm start"),
    ({"search": "sometimes"}, "search"),
])
def test_auto_refuses_what_it_cannot_measure(overrides, message):
    with pytest.raises(ConfigError, match=message):
        RunConfig.build({**AUTO, **overrides}).validate()


def test_above_the_break_even_the_picks_are_dropped_and_the_direct_search_takes_over_the_archive(monkeypatch):
    monkeypatch.setattr(auto_search, "BREAK_EVEN_COST_RATIO", 0.0)
    runner = make_runner()
    first = runner.step()
    size = len(runner.archive)
    second = runner.step()
    assert "auto_direct" not in first
    assert second["auto_direct"] == 1.0 and second["auto_cost_ratio"] > 1
    # The surrogate trained and exploited in this step, then MAP-Elites' first batch (5 x 30) was evaluated.
    assert second["time_exploit"] > 0 and second["evaluated_this_iteration"] == 150
    assert isinstance(runner.proposer, DirectQD) and runner.search_choice.direct
    assert runner.proposer.archive is runner.archive and len(runner.archive) > size
    runner.run()
    assert runner.evals == AUTO["budget"]
    assert sum("auto_direct" in row for row in runner.history) == 1
    assert all("time_exploit" not in row for row in runner.history[2:])


def test_picks_that_take_longer_than_their_allowance_stop_there_and_the_direct_search_takes_over(monkeypatch):
    monkeypatch.setattr(runner_module, "pick_allowance", lambda *args, **kwargs: 1e-9)
    runner = make_runner()
    runner.step()
    second = runner.step()
    # The picks' evaluation stopped at once: the levels begun were evaluated, kept and learned from.
    assert 1 <= second["evaluated_this_iteration"] < SMALL_RUN["selection.count"]
    assert second["auto_direct"] == 1.0 and second["auto_cost_ratio"] > auto_search.BREAK_EVEN_COST_RATIO
    assert isinstance(runner.proposer, DirectQD)
    assert runner.evals == SMALL_RUN["n_rand"] + second["evaluated_this_iteration"]
    runner.run()
    assert runner.evals == AUTO["budget"]


def test_below_the_break_even_the_run_is_dsages_bit_for_bit(monkeypatch):
    monkeypatch.setattr(auto_search, "BREAK_EVEN_COST_RATIO", float("inf"))
    auto = make_runner(budget=SMALL_RUN["budget"])
    auto.run()
    fixed = make_runner(budget=SMALL_RUN["budget"], search="fixed")
    fixed.run()
    assert isinstance(auto.proposer, SurrogateAssisted) and not auto.search_choice.direct
    assert archive_snapshot(auto.archive) == archive_snapshot(fixed.archive)


@pytest.mark.parametrize("steps", [1, 2, 3])
def test_a_run_resumes_exactly_before_at_and_after_the_switch(monkeypatch, steps):
    monkeypatch.setattr(auto_search, "BREAK_EVEN_COST_RATIO", 0.0)
    reference = make_runner()
    reference.run()
    interrupted = make_runner()
    for _ in range(steps):
        interrupted.step()
    state = pickle.loads(pickle.dumps(interrupted.state_dict()))
    resumed = make_runner()
    resumed.load_state_dict(state)
    resumed.run()
    assert archive_snapshot(resumed.archive) == archive_snapshot(reference.archive)
    if steps >= 2:  # the choice was made before the stop: the resumed run holds that one (its own times differ)
        assert resumed.search_choice == interrupted.search_choice
    assert isinstance(resumed.proposer, DirectQD)
