"""The pipelined outer loop (``pipeline = true``): iteration k+1's picks are chosen while iteration k's are evaluated."""

import json
import pickle

import pytest

from dsage_ray.config import ConfigError, RunConfig
from dsage_ray.core.runner import DSAGE
from tests.core.test_evaluation import ElsewhereEvaluator
from tests.core.test_runner import archive_snapshot
from tests.fakes import SMALL_RUN, BitmapDomain

PIPELINED = {**SMALL_RUN, "budget": 110, "pipeline": True}


def make_runner(evaluator_factory=None, **overrides) -> DSAGE:
    domain = BitmapDomain()
    evaluator = None if evaluator_factory is None else evaluator_factory(domain)
    return DSAGE(config=RunConfig.build({**PIPELINED, **overrides}), domain=domain, evaluator=evaluator)


def untimed(history) -> str:
    return json.dumps([{k: v for k, v in row.items() if "time" not in k} for row in history], sort_keys=True)


@pytest.fixture(scope="module")
def reference():
    """A pipelined run in this process, with (iteration proposed, evaluations its surrogate had) per proposal."""
    runner = make_runner()
    seen: list[tuple[int, int]] = []
    propose = runner.proposer.inner.propose

    def recording_propose(*, outer_iteration):
        seen.append((outer_iteration, len(runner.dataset)))
        return propose(outer_iteration=outer_iteration)

    runner.proposer.inner.propose = recording_propose
    runner.run()
    return runner, seen


def test_overlapping_the_evaluations_changes_nothing_but_the_timings(reference):
    in_process, _ = reference
    elsewhere = make_runner(ElsewhereEvaluator)
    elsewhere.run()
    assert in_process.evals == elsewhere.evals == PIPELINED["budget"]
    assert len(in_process.history) >= 4
    assert archive_snapshot(elsewhere.archive) == archive_snapshot(in_process.archive)
    assert untimed(elsewhere.history) == untimed(in_process.history)
    # The driver worked while a batch was out from the second step on, and only then.
    assert [row.get("time_overlapped", 0) > 0 for row in elsewhere.history][:2] == [False, True]
    assert not any("time_overlapped" in row for row in in_process.history)
    # The last iteration leaves no picks behind.
    assert in_process.proposer.pending is None and in_process.state_dict()["pending_proposal"] is None


def test_each_pick_is_chosen_by_a_surrogate_one_batch_behind(reference):
    runner, seen = reference
    evals_after = [0] + [int(row["evals"]) for row in runner.history]  # evaluations learned after each iteration
    assert [iteration for iteration, _ in seen] == list(range(len(runner.history)))
    for iteration, known in seen[2:]:
        assert known == evals_after[iteration - 1], iteration
    assert seen[1] == (1, evals_after[1])  # the first picks wait for the random batch


def test_a_resume_continues_from_the_saved_next_picks(reference):
    uninterrupted, _ = reference
    interrupted = make_runner()
    interrupted.step()
    interrupted.step()
    state = pickle.loads(pickle.dumps(interrupted.state_dict()))
    assert state["pending_proposal"] is not None
    resumed = make_runner(ElsewhereEvaluator)
    resumed.load_state_dict(state)
    assert resumed.proposer.pending is not None
    resumed.run()
    assert archive_snapshot(resumed.archive) == archive_snapshot(uninterrupted.archive)
    assert untimed(resumed.history) == untimed(uninterrupted.history)


def test_pipeline_needs_a_surrogate():
    with pytest.raises(ConfigError, match="pipeline"):
        RunConfig.build({**PIPELINED, "variant": "map_elites"})


def test_elite_mutants_are_chosen_alike_whether_or_not_the_evaluations_overlap():
    keys = {"selection.elite_mutants": 4}
    in_process, elsewhere = make_runner(**keys), make_runner(ElsewhereEvaluator, **keys)
    in_process.run()
    elsewhere.run()
    assert archive_snapshot(elsewhere.archive) == archive_snapshot(in_process.archive)
    assert untimed(elsewhere.history) == untimed(in_process.history)
    assert [row.get("selection_elite_mutants") for row in in_process.history][1:] == [4.0] * (
        len(in_process.history) - 1)


def test_a_screen_ranked_by_its_errors_learns_each_batch_against_its_own_screen_and_resumes_when_pipelined():
    from tests.fakes import ScreeningBitmapDomain

    # 80 evaluations: the 40 after the random ones still hold screened batches, and the later ones cost the most.
    keys = {**PIPELINED, "budget": 80, "selection.screen_episodes": 1, "selection.screen_gain": True}

    def screening(evaluator_factory=None) -> DSAGE:
        domain = ScreeningBitmapDomain()
        return DSAGE(config=RunConfig.build(keys), domain=domain,
                     evaluator=None if evaluator_factory is None else evaluator_factory(domain))

    in_process, elsewhere = screening(), screening(ElsewhereEvaluator)
    in_process.run()
    elsewhere.run()
    assert archive_snapshot(elsewhere.archive) == archive_snapshot(in_process.archive)
    assert untimed(elsewhere.history) == untimed(in_process.history)
    # The screen is exact here: had a batch been paired with the next proposal's screen, errors would show.
    errors = in_process.proposer.screen.errors
    assert len(errors) > 0 and (errors.actual == errors.predicted).all()
    interrupted = screening()
    interrupted.step()
    interrupted.step()
    state = pickle.loads(pickle.dumps(interrupted.state_dict()))
    assert state["pending_proposal"]["screened"] is not None
    resumed = screening(ElsewhereEvaluator)
    resumed.load_state_dict(state)
    resumed.run()
    assert archive_snapshot(resumed.archive) == archive_snapshot(in_process.archive)
    assert untimed(resumed.history) == untimed(in_process.history)
