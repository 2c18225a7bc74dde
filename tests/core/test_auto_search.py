import dataclasses
import pickle

import numpy as np
import pytest

from dsage_ray.config import ConfigError, RunConfig
from dsage_ray.core import auto_search
from dsage_ray.core import auto_proposer
from dsage_ray.core.auto_search import (SearchChoice, choose_by_time_left, choose_during_random, choose_search,
                                        direct_config, direct_variant, probe_allowance, random_level_seconds)
from dsage_ray.core.proposers import DirectQD, SurrogateAssisted
from dsage_ray.core.runner import DSAGE
from tests.core.test_runner import archive_snapshot
from tests.fakes import SMALL_RUN, BitmapDomain

#: Long enough for the direct search to run after the choice (iteration 0: 40 random levels; MAP-Elites: 150 a batch).
AUTO = {**SMALL_RUN, "budget": 200, "search": "auto"}


#: A surrogate that picks 5 or so levels in its first iteration on the fake domain: a probe of 2 leaves a rest.
PICKING = {"variant": "dsage_only_anc", "surrogate.epochs": 20, "qd.exploit_iterations": 20}


def make_runner(**overrides) -> DSAGE:
    return DSAGE(config=RunConfig.build({**AUTO, **overrides}), domain=BitmapDomain())


@pytest.fixture
def probe_two(monkeypatch):
    monkeypatch.setattr(auto_proposer, "PROBE_PICKS", 2)


@pytest.fixture
def slow_surrogate(monkeypatch):
    """A first proposal projected at 10^9 s: no surrogate iteration fits in the time left."""
    monkeypatch.setattr(SurrogateAssisted, "projected_proposal_seconds", lambda self: 1e9)


@pytest.fixture
def slow_random_levels(monkeypatch):
    """Random levels timed at 10^9 times their seconds: the rest of the random iteration would use up the time."""
    real = auto_proposer.choose_during_random
    monkeypatch.setattr(auto_proposer, "choose_during_random",
                        lambda **numbers: real(**{**numbers, "seconds": numbers["seconds"] * 1e9}))


@pytest.fixture
def after_random(monkeypatch):
    """No look during the random iteration: every random level is evaluated before the first look."""
    monkeypatch.setattr(auto_proposer, "RANDOM_LEVELS_TIMED", 10**9)


def random_row(seconds=2.0, levels=40):
    return {"time_evaluate": seconds, "evaluated_this_iteration": float(levels)}


def test_a_picks_cost_is_the_surrogates_seconds_spread_over_the_picks_plus_the_probes_mean_evaluation():
    choice = choose_search([random_row(2.0, 40)], surrogate_seconds=5.0, picks=25, probe_seconds=2.4, probed=8,
                           direct_variant="map_elites")
    assert choice.random_level_seconds == pytest.approx(0.05)
    assert choice.surrogate_level_seconds == pytest.approx(5.0 / 25 + 2.4 / 8)
    assert choice.cost_ratio == pytest.approx(0.5 / 0.05)
    assert choice.direct is (choice.cost_ratio > auto_search.BREAK_EVEN_COST_RATIO)


def test_a_probe_cut_at_its_allowance_has_its_picks_at_the_break_even_or_past_it():
    history = [random_row(2.0, 40)]
    allowance = probe_allowance(history, surrogate_seconds=1.0, picks=25, probed=8)
    assert allowance == pytest.approx((auto_search.BREAK_EVEN_COST_RATIO * 0.05 - 0.04) * 8) and allowance > 0
    for probed in (1, 3, 8):  # the probe stopped after these picks, having taken its allowance
        choice = choose_search(history, surrogate_seconds=1.0, picks=25, probe_seconds=allowance, probed=probed,
                               direct_variant="map_elites")
        assert choice.cost_ratio >= auto_search.BREAK_EVEN_COST_RATIO - 1e-9
    # A surrogate that alone costs past the break-even leaves the probe no time: one pick, then the choice.
    assert probe_allowance(history, surrogate_seconds=500.0, picks=25, probed=8) == 0.0


@pytest.mark.parametrize("probe_seconds, direct", [(0.1, False), (100.0, True)])
def test_the_break_even_decides(probe_seconds, direct):
    choice = choose_search([random_row(2.0, 40)], surrogate_seconds=0.5, picks=25, probe_seconds=probe_seconds,
                           probed=8, direct_variant="cma_me")
    assert choice.direct is direct
    assert ("continuing with cma_me" in choice.reason) is direct
    assert f"{choice.cost_ratio:.2f}×" in choice.reason


def test_a_choice_round_trips_through_its_metrics_and_state():
    choice = choose_search([random_row()], surrogate_seconds=100.0, picks=25, probe_seconds=1.0, probed=8,
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


def test_above_the_break_even_the_probed_picks_are_kept_the_rest_dropped_and_the_direct_search_continues(
        monkeypatch, probe_two):
    monkeypatch.setattr(auto_search, "BREAK_EVEN_COST_RATIO", 0.0)
    runner = make_runner(**PICKING)
    first = runner.step()
    second = runner.step()
    assert "auto_direct" not in first
    assert second["auto_direct"] == 1.0 and second["auto_cost_ratio"] > 0
    # The surrogate trained and picked 5 levels. A break-even of 0 leaves the probe no time: its first pick was
    # evaluated (and learned from), the rest dropped.
    assert second["time_exploit"] > 0 and second["surrogate_archive_size"] >= 5
    assert second["evaluated_this_iteration"] == 1 and runner.evals == SMALL_RUN["n_rand"] + 1
    assert isinstance(runner.proposer.inner, DirectQD) and runner.proposer.choice.direct
    assert runner.proposer.inner.archive is runner.archive
    third = runner.step()
    assert third["evaluated_this_iteration"] == 150 and "time_exploit" not in third  # MAP-Elites' 5 x 30
    runner.run()
    assert runner.evals == AUTO["budget"]
    assert sum("auto_direct" in row for row in runner.history) == 1


def test_below_the_break_even_the_probe_and_the_rest_make_dsages_run_bit_for_bit(monkeypatch, probe_two):
    monkeypatch.setattr(auto_search, "BREAK_EVEN_COST_RATIO", float("inf"))
    auto = make_runner(budget=SMALL_RUN["n_rand"] + 10, **PICKING)
    auto.run()
    fixed = make_runner(budget=SMALL_RUN["n_rand"] + 10, search="fixed", **PICKING)
    fixed.run()
    assert isinstance(auto.proposer.inner, SurrogateAssisted) and not auto.proposer.choice.direct
    # More picks than the probe's 2 (how many depends on the CPU's kernels): the rest after the probe is DSAGE's too.
    assert auto.history[1]["evaluated_this_iteration"] == fixed.history[1]["evaluated_this_iteration"] > 2
    assert archive_snapshot(auto.archive) == archive_snapshot(fixed.archive)


@pytest.mark.parametrize("steps", [1, 2, 3])
def test_a_run_resumes_exactly_before_at_and_after_the_switch(monkeypatch, probe_two, steps):
    monkeypatch.setattr(auto_search, "BREAK_EVEN_COST_RATIO", 0.0)
    reference = make_runner(**PICKING)
    reference.run()
    interrupted = make_runner(**PICKING)
    for _ in range(steps):
        interrupted.step()
    state = pickle.loads(pickle.dumps(interrupted.state_dict()))
    resumed = make_runner(**PICKING)
    resumed.load_state_dict(state)
    resumed.run()
    assert archive_snapshot(resumed.archive) == archive_snapshot(reference.archive)
    if steps >= 2:  # the choice was made before the stop: the resumed run holds that one (its own times differ)
        assert resumed.proposer.choice == interrupted.proposer.choice
    assert isinstance(resumed.proposer.inner, DirectQD)


#: Far more than the run can take: it ends on its evaluations; only the look at the time left reads it.
LONG = 1e6


def test_the_time_left_is_counted_in_surrogate_iterations_at_their_cheapest():
    history = [random_row(2.0, 40)]  # a random level: 0.05 s
    # A proposal of 5 s over 25 picks, then each pick at a random level's 0.05 s: an iteration of 6.25 s at least.
    short = choose_by_time_left(random_seconds=random_level_seconds(history), time_left=12.5, proposal_seconds=5.0,
                                picks=25, evals_left=1000, direct_variant="cma_me")
    assert short.iterations_left == pytest.approx(2.0) and short.time_left == 12.5
    assert short.surrogate_level_seconds == pytest.approx(0.25) and short.cost_ratio == pytest.approx(5.0)
    assert short.direct and short.by_time_left
    assert "room for 2.0 surrogate iterations of at least 6 s; DSAGE needs 3" in short.reason
    long = choose_by_time_left(random_seconds=0.05, time_left=100.0, proposal_seconds=5.0, picks=25, evals_left=1000,
                               direct_variant="cma_me")
    assert long.iterations_left == pytest.approx(16.0) and not long.direct and not long.by_time_left
    # Kept until the probe, whose choice carries the look's numbers (and its own reason).
    probed = choose_search(history, surrogate_seconds=5.0, picks=25, probe_seconds=100.0, probed=8,
                           direct_variant="cma_me", before=long)
    assert probed.direct and probed.iterations_left == long.iterations_left and "break-even" in probed.reason
    row = {"outer_iteration": 1.0, **short.metrics()}
    assert row["auto_iterations_left"] == pytest.approx(2.0)
    assert SearchChoice.from_metrics(row, variant="cma_me") == short


def test_with_too_little_time_left_the_direct_search_takes_over_before_the_surrogate_trains(after_random,
                                                                                            slow_surrogate):
    runner = make_runner(time_budget=LONG)
    first = runner.step()
    second = runner.step()
    assert "auto_direct" not in first
    assert second["auto_direct"] == 1.0 and 0 < second["auto_iterations_left"] < 1e12
    assert second["auto_time_left_s"] == pytest.approx(LONG - first["wall_time"], abs=5.0)
    assert runner.proposer.choice.by_time_left and "DSAGE needs" in runner.proposer.choice.reason
    # Nothing trained: the direct search proposed this iteration's batch (MAP-Elites' 5 x 30).
    assert "time_train" not in second and "surrogate_loss" not in second and second["time_auto_look"] > 0
    assert second["evaluated_this_iteration"] == 150 and isinstance(runner.proposer.inner, DirectQD)
    runner.run()
    # The look drew nothing from the run's streams: the run is the random iteration, then the direct search.
    by_hand = make_runner(time_budget=LONG)
    by_hand.step()
    by_hand.proposer.continue_direct(runner.proposer.choice)
    by_hand.run()
    assert archive_snapshot(runner.archive) == archive_snapshot(by_hand.archive)


def test_a_look_that_keeps_dsage_leaves_its_run_bit_for_bit_and_its_numbers_in_the_choice(monkeypatch, probe_two):
    monkeypatch.setattr(auto_search, "MIN_SURROGATE_ITERATIONS", 0)
    monkeypatch.setattr(auto_search, "BREAK_EVEN_COST_RATIO", float("inf"))
    budget = SMALL_RUN["n_rand"] + 10
    auto = make_runner(budget=budget, time_budget=LONG, **PICKING)
    auto.run()
    fixed = make_runner(budget=budget, time_budget=LONG, search="fixed", **PICKING)
    fixed.run()
    assert not auto.proposer.choice.direct and auto.proposer.choice.iterations_left > 0
    assert auto.history[1]["auto_iterations_left"] == auto.proposer.choice.iterations_left
    assert archive_snapshot(auto.archive) == archive_snapshot(fixed.archive)
    assert auto.history[-1]["surrogate_loss"] == fixed.history[-1]["surrogate_loss"]


@pytest.mark.parametrize("steps", [1, 2])
def test_a_run_resumes_exactly_across_a_switch_by_the_time_left(after_random, slow_surrogate, steps):
    reference = make_runner(time_budget=LONG)
    reference.run()
    interrupted = make_runner(time_budget=LONG)
    for _ in range(steps):
        interrupted.step()
    resumed = make_runner(time_budget=LONG)
    resumed.load_state_dict(pickle.loads(pickle.dumps(interrupted.state_dict())))
    resumed.run()
    assert archive_snapshot(resumed.archive) == archive_snapshot(reference.archive)
    assert isinstance(resumed.proposer.inner, DirectQD) and resumed.proposer.choice.by_time_left
    assert direct_variant(resumed.config) == "map_elites"


def test_during_the_random_iteration_the_rest_is_projected_at_the_first_levels_seconds():
    # 8 levels of 1 s; 32 more would take 32 s; a surrogate iteration of 10 picks takes 10 s at the least.
    room = choose_during_random(seconds=8.0, timed=8, random_levels=40, time_left=100.0, picks=10, evals_left=1000,
                                direct_variant="cma_me")
    assert room.time_left == pytest.approx(68.0) and room.iterations_left == pytest.approx(6.8) and not room.direct
    short = choose_during_random(seconds=8.0, timed=8, random_levels=40, time_left=40.0, picks=10, evals_left=1000,
                                 direct_variant="cma_me")
    assert short.iterations_left == pytest.approx(0.8) and short.direct and short.by_time_left
    assert "after 8 random levels (they took 1 s each: the rest of the random iteration would leave 8 s" in short.reason
    spent = choose_during_random(seconds=8.0, timed=8, random_levels=40, time_left=20.0, picks=10, evals_left=1000,
                                 direct_variant="cma_me")
    assert spent.direct and "would use up the time budget" in spent.reason
    row = {"outer_iteration": 1.0, **short.metrics()}
    assert row["auto_random_levels_timed"] == 8.0
    assert SearchChoice.from_metrics(row, variant="cma_me") == short
    assert SearchChoice.from_state_dict(pickle.loads(pickle.dumps(short.state_dict()))) == short


def test_random_levels_that_leave_too_little_time_are_dropped_and_the_direct_search_continues_from_the_first(
        slow_random_levels):
    runner = make_runner(time_budget=LONG)
    first = runner.step()
    timed = auto_proposer.RANDOM_LEVELS_TIMED
    assert first["auto_direct"] == 1.0 and first["auto_random_levels_timed"] == timed
    assert first["evaluated_this_iteration"] == timed == runner.evals and len(runner.archive) >= 1
    assert isinstance(runner.proposer.inner, DirectQD) and runner.proposer.choice.random_levels_timed == timed
    assert f"after {timed} random levels" in runner.proposer.choice.reason
    # Nothing trained, nothing more looked at: MAP-Elites' 5 x 30 from the next iteration on.
    second = runner.step()
    assert second["evaluated_this_iteration"] == 150 and "time_train" not in second and "auto_direct" not in second
    runner.run()
    assert sum("auto_direct" in row for row in runner.history) == 1


def test_with_time_for_the_surrogate_every_random_level_is_evaluated_as_in_the_fixed_run(monkeypatch):
    monkeypatch.setattr(auto_search, "MIN_SURROGATE_ITERATIONS", 0)
    auto = make_runner(time_budget=LONG)
    first = auto.step()
    fixed = make_runner(time_budget=LONG, search="fixed")
    fixed.step()
    assert "auto_direct" not in first and auto.proposer.choice is None
    assert first["evaluated_this_iteration"] == SMALL_RUN["n_rand"]
    assert archive_snapshot(auto.archive) == archive_snapshot(fixed.archive)


def test_a_run_resumes_exactly_across_a_switch_during_the_random_iteration(slow_random_levels):
    reference = make_runner(time_budget=LONG)
    reference.run()
    interrupted = make_runner(time_budget=LONG)
    interrupted.step()
    resumed = make_runner(time_budget=LONG)
    resumed.load_state_dict(pickle.loads(pickle.dumps(interrupted.state_dict())))
    resumed.run()
    assert archive_snapshot(resumed.archive) == archive_snapshot(reference.archive)
    assert isinstance(resumed.proposer.inner, DirectQD) and resumed.proposer.choice.random_levels_timed is not None


def test_the_look_repeats_through_the_random_iteration_until_the_levels_so_far_say_switch(monkeypatch):
    looked = []

    def choose_after_three_parts(**numbers):  # levels slow to play turn up late in the random iteration
        looked.append(numbers["timed"])
        return dataclasses.replace(choose_during_random(**numbers), direct=numbers["timed"] >= 24)

    monkeypatch.setattr(auto_proposer, "choose_during_random", choose_after_three_parts)
    runner = make_runner(time_budget=LONG)
    first = runner.step()
    assert looked == [8, 16, 24] and first["evaluated_this_iteration"] == 24 == runner.evals
    assert first["auto_random_levels_timed"] == 24 and isinstance(runner.proposer.inner, DirectQD)


def test_where_fewer_iterations_spend_the_evaluation_budget_dsage_needs_only_those():
    # 240 evaluations left after the random ones, all of them one iteration's picks: one iteration spends them.
    finishing = choose_by_time_left(random_seconds=0.25, time_left=105.0, proposal_seconds=0.0, picks=240,
                                    evals_left=240, direct_variant="cross_entropy")
    assert finishing.iterations_left == pytest.approx(1.75) and finishing.iterations_needed == 1
    assert not finishing.direct and not finishing.by_time_left
    long_budget = choose_by_time_left(random_seconds=0.25, time_left=105.0, proposal_seconds=0.0, picks=240,
                                      evals_left=10_000, direct_variant="cross_entropy")
    assert long_budget.direct and long_budget.iterations_needed == auto_search.MIN_SURROGATE_ITERATIONS
    short = choose_during_random(seconds=2.0, timed=8, random_levels=60, time_left=40.0, picks=240, evals_left=240,
                                 direct_variant="cross_entropy")
    assert short.direct and "DSAGE needs 1)" in short.reason
    assert SearchChoice.from_metrics({"outer_iteration": 1.0, **short.metrics()}, variant="cross_entropy") == short


@pytest.mark.parametrize("method, expected", [("downsample", "blocks"), ("random", "count"), ("full", "cells")])
def test_a_surrogate_iteration_is_counted_at_one_pick_per_block_at_most(method, expected):
    runner = make_runner(time_budget=LONG, **{"selection.method": method, "selection.count": 10_000,
                                             "selection.block": (4, 4), "budget": 100_000})
    dims = runner.archive.dims
    count = {"blocks": -(-dims[0] // 4) * -(-dims[1] // 4), "count": 10_000, "cells": dims[0] * dims[1]}[expected]
    assert runner.proposer.surrogate_picks(0) == count
    assert runner.proposer.surrogate_picks(100_000 - 7) == 7  # within the evaluation budget


def _direct_search(config, domain, *, levels_before=None, handover):
    """A direct search over a fresh run archive; with ``levels_before``, after those levels entered it and a run
    whose QD stream drew two more seeds (a surrogate's, its archive's), as a DSAGE run's has by then."""
    from dsage_ray.core.proposers import domain_archive
    from dsage_ray.core.seeds import RunSeeds

    seeds = RunSeeds(seed=config.seed)
    archive = domain_archive(domain, with_occupancy=True, seed=seeds.next_qd_seed())
    if levels_before is not None:
        for _ in range(2):
            seeds.next_qd_seed()
        results = [domain.evaluate(level, seed=i) for i, level in enumerate(levels_before)]
        archive.add(levels_before, [r.objective for r in results], [r.measures for r in results],
                    occupancy=[r.occupancy for r in results])
    return DirectQD(config=config, domain=domain, archive=archive, seeds=seeds, handover=handover)


def _play(search, domain, outer_iteration):
    from dsage_ray.core.proposers import EvaluatedBatch

    proposal = search.propose(outer_iteration=outer_iteration)
    results = [domain.evaluate(level, seed=1000 * outer_iteration + i) for i, level in enumerate(proposal.solutions)]
    search.learn(EvaluatedBatch.collect(proposal, results, domain=domain, outer_iteration=outer_iteration))
    return proposal.solutions


class LatentBitmapDomain(BitmapDomain):
    """:class:`BitmapDomain` with real-valued solutions (a wall where a value is over 0.5), as CMA-ES needs."""

    solution_dtype = np.float64


@pytest.mark.parametrize("handover", [True, False])
def test_a_cma_me_that_takes_over_asks_what_it_would_have_from_the_start_and_keeps_the_levels_before(handover):
    domain = LatentBitmapDomain()
    config = RunConfig.build({**SMALL_RUN, "variant": "map_elites", "qd.emitter": "cma_me", "qd.sigma0": 0.3})
    from_start = _direct_search(config, domain, handover=False)
    random_levels = domain.random_solutions(40, np.random.default_rng(7)).astype(np.float64)
    taking_over = _direct_search(config, domain, levels_before=random_levels, handover=handover)
    before = _elites(taking_over.archive)
    same = [np.array_equal(_play(from_start, domain, i), _play(taking_over, domain, i)) for i in range(1, 6)]
    # Without a handover the emitters rank against (and restart from) the levels before, with another seed.
    assert all(same) if handover else not any(same)
    if handover:
        # Every level is in the run's archive, at least as good in every cell; the emitters' own holds what they
        # asked, as the run from the start does.
        after, alone = _elites(taking_over.archive), _elites(from_start.archive)
        assert all(after[cell] >= objective for cell, objective in {**before, **alone}.items())
        assert archive_snapshot(taking_over.scheduler.archive) == archive_snapshot(from_start.archive)
        assert len(after) > len(alone)


def _elites(archive) -> dict[int, float]:
    data = archive.data()
    return dict(zip(data["index"].tolist(), data["objective"].tolist()))


def test_a_direct_search_that_took_over_resumes_from_a_checkpoint_with_its_two_archives_linked(tmp_path):
    from dsage_ray.core.checkpoint import load_checkpoint, save_checkpoint

    domain = LatentBitmapDomain()
    config = RunConfig.build({**SMALL_RUN, "variant": "map_elites", "qd.emitter": "cma_me", "qd.sigma0": 0.3,
                              "seed": 3})
    random_levels = domain.random_solutions(40, np.random.default_rng(7)).astype(np.float64)
    reference = _direct_search(config, domain, levels_before=random_levels, handover=True)
    interrupted = _direct_search(config, domain, levels_before=random_levels, handover=True)
    for i in (1, 2):
        _play(reference, domain, i), _play(interrupted, domain, i)
    path = save_checkpoint({"config": config.to_dict(), "archive": interrupted.archive,
                            **interrupted.state_dict()}, tmp_path / "state.ckpt")
    resumed = _direct_search(config, domain, handover=True)
    resumed.load_state_dict(load_checkpoint(path))
    assert resumed.scheduler.result_archive is resumed.archive is not resumed.scheduler.archive
    for i in (3, 4):
        assert np.array_equal(_play(reference, domain, i), _play(resumed, domain, i))
    assert archive_snapshot(resumed.archive) == archive_snapshot(reference.archive)


def test_a_batch_that_cannot_be_told_after_a_handover_enters_both_archives_and_keeps_them_linked():
    from dsage_ray.core.proposers import EvaluatedBatch

    domain = LatentBitmapDomain()
    config = RunConfig.build({**SMALL_RUN, "variant": "map_elites", "qd.emitter": "cma_me", "qd.sigma0": 0.3})
    search = _direct_search(config, domain, levels_before=domain.random_solutions(40, np.random.default_rng(7))
                            .astype(np.float64), handover=True)
    proposal = search.propose(outer_iteration=1)
    results = [domain.evaluate(level, seed=i) for i, level in enumerate(proposal.solutions[:5])]  # a budget cut it
    search.learn(EvaluatedBatch.collect(proposal, results, domain=domain, outer_iteration=1))
    own = search.scheduler.archive
    assert own is not search.archive and search.scheduler.result_archive is search.archive
    assert 0 < len(own) <= 5 and set(_elites(own)) <= set(_elites(search.archive))
    search.propose(outer_iteration=2)  # the cycle was closed: it asks again
