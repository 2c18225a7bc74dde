"""The outer loop's two strategies on their own (dsage_ray.core.proposers): what each proposes, and what it learns.

:class:`SurrogateAssisted` is DSAGE: a random start, then train → exploit → select. :class:`DirectQD` is a QD
optimizer on the ground-truth archive (MAP-Elites, CMA-ME, DR), with an optional screen. Whole runs of them are in
tests/core/test_runner.py and test_golden.py; these drive one proposer by hand, without a runner.
"""

from __future__ import annotations

import numpy as np
import pytest

from dsage_ray.config import RunConfig
from dsage_ray.core.evaluation import evaluate_safely
from dsage_ray.core.proposers import DirectQD, EvaluatedBatch, Proposal, SurrogateAssisted, domain_archive
from dsage_ray.core.seeds import RunSeeds
from dsage_ray.qd.optimizer import MAP_ELITES_RANDOM_BATCHES
from tests.fakes import SMALL_RUN, BitmapDomain, ScreeningBitmapDomain


def evaluated(domain, proposal: Proposal, *, outer_iteration: int) -> EvaluatedBatch:
    """The proposal's solutions evaluated in this process (a raising evaluation is a failed result)."""
    results = [evaluate_safely(domain, solution, seed=i) for i, solution in enumerate(proposal.solutions)]
    return EvaluatedBatch.collect(proposal, results, domain=domain, outer_iteration=outer_iteration)


def cells(archive) -> set[int]:
    return set(np.asarray(archive.data("index")).tolist())


# ------------------------------------------------------------------------------------------- DSAGE


def dsage(domain=None, **keys):
    config = RunConfig.build({**SMALL_RUN, **keys})
    domain = domain or BitmapDomain()
    archive = domain_archive(domain, with_occupancy=True, seed=0)
    proposer = SurrogateAssisted(config=config, domain=domain, archive=archive, seeds=RunSeeds(seed=0),
                                 evaluator=None)
    return proposer, domain, archive


def test_dsage_starts_with_n_rand_random_levels_and_no_surrogate():
    proposer, domain, archive = dsage()
    before = {name: p.detach().clone() for name, p in proposer.surrogate.model.state_dict().items()}
    proposal = proposer.propose(outer_iteration=0)
    assert proposal.solutions.shape == (SMALL_RUN["n_rand"], domain.solution_dim)
    # The run's own random stream draws them, as the domain samples them.
    expected = domain.random_solutions(SMALL_RUN["n_rand"], RunSeeds(seed=0).rng)
    np.testing.assert_array_equal(proposal.solutions, expected)
    assert proposal.predicted is None and proposal.screened is None and "train" not in proposal.times
    assert all((p == before[name]).all() for name, p in proposer.surrogate.model.state_dict().items())
    assert len(archive) == 0  # proposing adds nothing


def test_dsage_learns_the_successful_results_into_the_archive_and_the_dataset():
    # Levels with 30 walls raise: they stay out of both.
    proposer, domain, archive = dsage(domain=BitmapDomain(fail_on=tuple(range(28, 33)), fail_once=False))
    batch = evaluated(domain, proposer.propose(outer_iteration=0), outer_iteration=0)
    assert 0 < len(batch.ok) < len(batch.solutions)
    assert proposer.learn(batch) == {}  # a random batch: nothing was predicted, so no errors to report
    assert len(proposer.dataset) == len(batch.ok) and proposer.last_predictions is None
    assert cells(archive) == set(archive.index_of(batch.measures).tolist())
    walls = archive.data("solution").sum(axis=1)
    assert not ((walls >= 28) & (walls <= 32)).any()


def test_dsage_then_trains_exploits_and_selects_elites_of_the_surrogate_archive_with_their_predictions():
    proposer, domain, archive = dsage()
    proposer.learn(evaluated(domain, proposer.propose(outer_iteration=0), outer_iteration=0))
    proposal = proposer.propose(outer_iteration=1)
    assert {"train", "exploit", "select"} <= set(proposal.times)
    assert np.isfinite(proposal.metrics["surrogate_loss"]) and proposal.metrics["surrogate_epochs"] == 1
    picked = len(proposal.solutions)
    assert 0 < picked <= min(SMALL_RUN["selection.count"], proposal.metrics["surrogate_archive_size"])
    # Elites of distinct cells of the surrogate archive: distinct levels.
    assert len(np.unique(proposal.solutions, axis=0)) == picked
    # What the surrogate that chose them predicts, kept with them.
    again = proposer.surrogate.predict(domain.encode(proposal.solutions))
    np.testing.assert_allclose(proposal.predicted.measures, again.measures, rtol=1e-5, atol=1e-5)
    assert proposal.predicted.objective.shape == (picked,)

    batch = evaluated(domain, proposal, outer_iteration=1)
    metrics = proposer.learn(batch)
    # The errors of the model that chose the batch, one per head, named by the domain's measures.
    assert {"mae_objective", "mae_num_walls", "mae_top_walls"} <= set(metrics)
    assert all(np.isfinite(value) and value >= 0 for value in metrics.values())
    predicted, true = proposer.last_predictions
    np.testing.assert_array_equal(predicted, proposal.predicted.measures[batch.ok])
    np.testing.assert_array_equal(true, batch.measures)
    assert len(proposer.dataset) == SMALL_RUN["n_rand"] + picked


def test_dsage_adds_elite_mutants_beside_its_picks():
    proposer, domain, archive = dsage(**{"selection.elite_mutants": 5})
    proposer.learn(evaluated(domain, proposer.propose(outer_iteration=0), outer_iteration=0))
    proposal = proposer.propose(outer_iteration=1)
    assert proposal.metrics["selection_elite_mutants"] == 5
    assert len(proposal.predicted.objective) == len(proposal.solutions)  # the mutants are predicted too


def test_dsage_state_round_trips_into_a_new_proposer():
    proposer, domain, archive = dsage()
    proposer.learn(evaluated(domain, proposer.propose(outer_iteration=0), outer_iteration=0))
    proposer.propose(outer_iteration=1)  # trains
    state = {**proposer.state_dict(), "archive": archive, "last_predictions": proposer.last_predictions}
    assert state["scheduler"] is None  # DSAGE keeps no scheduler between iterations: each exploit starts afresh

    restored, _, _ = dsage()
    restored.load_state_dict(state)
    assert restored.archive is archive and len(restored.dataset) == len(proposer.dataset)
    for name, value in proposer.surrogate.model.state_dict().items():
        assert (restored.surrogate.model.state_dict()[name] == value).all(), name
    encoded = domain.encode(domain.random_solutions(8, np.random.default_rng(1)))
    np.testing.assert_array_equal(restored.surrogate.predict(encoded).measures,
                                  proposer.surrogate.predict(encoded).measures)


# ------------------------------------------------------------------------------------------- direct QD


def direct(variant: str = "map_elites", domain=None, **keys):
    config = RunConfig.build({**SMALL_RUN, "variant": variant, **keys})
    domain = domain or BitmapDomain()
    archive = domain_archive(domain, with_occupancy=True, seed=0)
    proposer = DirectQD(config=config, domain=domain, archive=archive, seeds=RunSeeds(seed=0))
    return proposer, domain, archive, config


@pytest.mark.parametrize("variant", ["map_elites", "dr"])
def test_direct_qd_asks_its_scheduler_and_the_tell_fills_the_ground_truth_archive(variant):
    proposer, domain, archive, config = direct(variant)
    batch_size = config.qd.num_emitters * config.qd.batch_size
    for iteration in range(3):
        proposal = proposer.propose(outer_iteration=iteration)
        assert proposal.solutions.shape == (batch_size, domain.solution_dim) and proposal.screened is None
        assert proposer.asked
        batch = evaluated(domain, proposal, outer_iteration=iteration)
        assert batch.complete and proposer.learn(batch) == {}
        # Told: each result entered the archive (a cell keeps its best).
        assert cells(archive) >= set(archive.index_of(batch.measures).tolist())
    assert proposer.scheduler.archive is archive


def test_a_batch_with_a_failure_is_not_told_but_its_successes_enter_the_archive():
    proposer, domain, archive, _ = direct(domain=BitmapDomain(fail_on=tuple(range(28, 33)), fail_once=False))
    scheduler = proposer.scheduler
    batch = evaluated(domain, proposer.propose(outer_iteration=0), outer_iteration=0)
    assert not batch.complete and batch.ok
    proposer.learn(batch)
    assert cells(archive) == set(archive.index_of(batch.measures).tolist())
    # The ask/tell cycle is closed without the batch: the next ask works.
    assert proposer.scheduler is not scheduler and proposer.scheduler.archive is archive
    assert len(proposer.propose(outer_iteration=1).solutions) == len(batch.solutions)


def test_map_elites_with_a_screen_asks_first_then_evaluates_screened_mutants_and_adds_them_itself():
    proposer, domain, archive, config = direct(domain=ScreeningBitmapDomain(), **{"selection.screen_episodes": 1})
    assert proposer.screen is not None
    for iteration in range(MAP_ELITES_RANDOM_BATCHES):
        proposal = proposer.propose(outer_iteration=iteration)
        assert proposer.asked and proposal.screened is None and domain.screened == 0
        proposer.learn(evaluated(domain, proposal, outer_iteration=iteration))
    scheduler, held = proposer.scheduler, cells(archive)
    proposal = proposer.propose(outer_iteration=MAP_ELITES_RANDOM_BATCHES)
    batch_size = config.qd.num_emitters * config.qd.batch_size
    assert not proposer.asked and domain.screened == round(config.experimental.screen_pool * batch_size)
    assert 0 < len(proposal.solutions) <= batch_size and proposal.screened.shape[0] == len(proposal.solutions)
    assert {"select", "screen"} <= set(proposal.times)
    batch = evaluated(domain, proposal, outer_iteration=MAP_ELITES_RANDOM_BATCHES)
    proposer.learn(batch)
    # Added directly, not told; the exact screen's picks land in new cells.
    assert proposer.scheduler is scheduler
    new = set(archive.index_of(batch.measures).tolist())
    assert new <= cells(archive) and not new & held


class ContinuousBitmapDomain(BitmapDomain):
    """:class:`BitmapDomain` over real-valued solutions (a cell is a wall above 0.5), which CMA-ES can search."""

    solution_dtype = np.float64

    def random_solutions(self, n: int, rng: np.random.Generator) -> np.ndarray:
        return rng.random((n, self.solution_dim))


def test_a_handed_over_cma_me_ranks_against_an_archive_of_its_own_while_every_level_enters_the_runs():
    proposer, domain, archive, config = direct("map_elites", domain=ContinuousBitmapDomain(),
                                               **{"qd.emitter": "cma_me"})
    assert proposer.scheduler.archive is archive  # from the start: the run's archive is the emitters' own
    prior = domain.random_solutions(30, np.random.default_rng(5))
    results = [domain.evaluate(s, seed=0) for s in prior]
    archive.add(prior, [r.objective for r in results], [r.measures for r in results],
                occupancy=[r.occupancy for r in results])
    handed = DirectQD(config=config, domain=domain, archive=archive, seeds=RunSeeds(seed=0), handover=True)
    assert handed.scheduler.archive is not archive and len(handed.scheduler.archive) == 0
    batch = evaluated(domain, handed.propose(outer_iteration=0), outer_iteration=0)
    held = len(archive)
    handed.learn(batch)
    assert len(handed.scheduler.archive) > 0 and len(archive) >= held
    assert set(archive.index_of(batch.measures).tolist()) <= cells(archive)
    assert cells(handed.scheduler.archive) <= cells(archive)


def test_a_handed_over_map_elites_reads_the_runs_archive():
    # Its emitters mutate elites of the archive they add to: after a handover, DSAGE's levels.
    proposer, domain, archive, config = direct()
    handed = DirectQD(config=config, domain=domain, archive=archive, seeds=RunSeeds(seed=0), handover=True)
    assert handed.scheduler.archive is archive


def test_direct_qd_state_round_trips_into_a_new_proposer():
    proposer, domain, archive, config = direct("dr")
    proposer.learn(evaluated(domain, proposer.propose(outer_iteration=0), outer_iteration=0))
    state = {**proposer.state_dict(), "archive": archive}
    assert state["surrogate"] is None and state["dataset"] is None
    restored = DirectQD(config=config, domain=domain, archive=domain_archive(domain, with_occupancy=True, seed=0),
                        seeds=RunSeeds(seed=0))
    restored.load_state_dict(state)
    assert restored.archive is archive and restored.scheduler is proposer.scheduler
    # The random emitter samples with the domain's code again (not kept in the checkpoint).
    assert len(restored.propose(outer_iteration=1).solutions) == config.qd.num_emitters * config.qd.batch_size
