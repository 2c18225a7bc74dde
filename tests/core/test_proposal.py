"""An iteration's agent simulation (dsage_ray.core.proposal.Simulation): each level keeps its seed whoever evaluates
it and in whatever parts, and the batch it gives is what was evaluated, in the proposal's order."""

from __future__ import annotations

import numpy as np

from dsage_ray.core.evaluation import InProcessEvaluator
from dsage_ray.core.proposal import Proposal, Simulation
from dsage_ray.surrogate.surrogate import Prediction
from tests.core.test_evaluation import ElsewhereEvaluator
from tests.fakes import BitmapDomain

LEVELS = 10


class SeedRecorder:
    """An evaluator that records (level sum, seed) per evaluation, then evaluates in this process."""

    def __init__(self, domain) -> None:
        self.inner = InProcessEvaluator(domain=domain)
        self.calls: list[list[tuple[int, int]]] = []

    def __call__(self, solutions, seeds):
        self.calls.append([(int(np.sum(s)), int(seed)) for s, seed in zip(solutions, seeds)])
        return self.inner(solutions, seeds)


def proposal(domain, count: int = LEVELS) -> Proposal:
    solutions = domain.random_solutions(count, np.random.default_rng(3))
    predicted = Prediction(objective=np.arange(count, dtype=np.float32),
                           measures=np.zeros((count, len(domain.measure_names)), np.float32), occupancy=None)
    return Proposal(solutions, predicted=predicted, screened=np.arange(count, dtype=np.float64)[:, None])


def simulation(domain, evaluator, *, budget_left: int = LEVELS, **kwargs) -> Simulation:
    made = proposal(domain)
    return Simulation(proposal=made, evaluator=evaluator, seeds=[1000 + i for i in range(budget_left)], evals=50,
                      budget=50 + budget_left, deadline=None, **kwargs)


def results_by_seed(batch) -> dict[int, tuple]:
    return {seed: (r.objective, tuple(r.measures)) for seed, r in zip(batch.seeds, batch.results)}


def test_levels_evaluated_in_parts_and_out_of_order_are_the_batch_one_evaluation_gives():
    domain = BitmapDomain()
    whole = simulation(domain, InProcessEvaluator(domain=domain))
    whole.evaluate()
    recorder = SeedRecorder(domain)
    parts = simulation(domain, recorder)
    parts.evaluate([7, 2])
    parts.evaluate(slice(0, 2))
    parts.evaluate([i for i in range(LEVELS) if i not in parts.results])
    one, split = (s.batch(domain=domain, outer_iteration=1) for s in (whole, parts))
    assert split.seeds == one.seeds == tuple(1000 + i for i in range(LEVELS))
    assert results_by_seed(split) == results_by_seed(one)
    np.testing.assert_array_equal(split.solutions, one.solutions)
    # Each level went to the evaluator with its own seed, whichever part it was in.
    sums = {seed: level_sum for call in recorder.calls for level_sum, seed in call}
    assert sums == {1000 + i: int(np.sum(level)) for i, level in enumerate(whole.solutions)}
    assert one.complete and split.complete


def test_a_batch_of_some_levels_keeps_their_predictions_and_screened_results_in_the_proposals_order():
    domain = BitmapDomain()
    some = simulation(domain, InProcessEvaluator(domain=domain))
    some.evaluate([8, 1, 4])
    batch = some.batch(domain=domain, outer_iteration=2)
    assert batch.seeds == (1001, 1004, 1008) and batch.outer_iteration == 2
    np.testing.assert_array_equal(batch.solutions, some.solutions[[1, 4, 8]])
    np.testing.assert_array_equal(batch.predicted.objective, [1.0, 4.0, 8.0])
    np.testing.assert_array_equal(batch.screened[:, 0], [1.0, 4.0, 8.0])


def test_the_budget_cuts_the_proposal_and_a_cut_batch_is_not_complete():
    domain = BitmapDomain()
    cut = simulation(domain, InProcessEvaluator(domain=domain), budget_left=6)
    assert cut.count == 6
    cut.evaluate()
    batch = cut.batch(domain=domain, outer_iteration=0)
    assert len(batch.solutions) == 6 and not batch.complete  # a QD scheduler's tell needs the whole batch


def test_a_deadline_passed_stops_after_the_first_level_and_the_earlier_of_two_deadlines_holds():
    domain = BitmapDomain()
    late = simulation(domain, InProcessEvaluator(domain=domain))
    late.deadline = 0.0  # long past
    assert len(late.evaluate()) == 1 and late.time_left() < 0
    early = simulation(domain, InProcessEvaluator(domain=domain))
    early.deadline = float("inf")
    assert len(early.evaluate(slice(0, 5), deadline=0.0)) == 1 and len(early.evaluate(slice(5, 10))) == 5
    assert simulation(domain, InProcessEvaluator(domain=domain)).time_left() is None


def test_the_progress_bar_counts_the_levels_already_evaluated_this_iteration():
    domain = BitmapDomain()
    heard: list[tuple[str, int, int]] = []
    parts = simulation(domain, InProcessEvaluator(domain=domain), progress=lambda *a: heard.append(a))
    parts.evaluate(slice(0, 4))
    parts.evaluate(slice(4, 10))
    assert [done for _, done, _ in heard] == list(range(51, 61))
    assert {(phase, total) for phase, _, total in heard} == {("evaluate", 60)}


def test_levels_started_elsewhere_are_kept_once_collected_and_phases_add_up():
    domain = BitmapDomain()
    elsewhere = simulation(domain, ElsewhereEvaluator(domain), times={"train": 1.0})
    running = elsewhere.start()
    assert running.overlapped and elsewhere.results == {}
    elsewhere.add_times({"train": 0.5, "exploit": 2.0})
    assert len(running.result()) == LEVELS and sorted(elsewhere.results) == list(range(LEVELS))
    assert elsewhere.times == {"train": 1.5, "exploit": 2.0}
