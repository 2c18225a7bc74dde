"""``InProcessEvaluator`` (evaluations in this process, on the run's torch threads when it is given them) and
``PendingEvaluation`` (a batch evaluated while the caller works)."""

import threading
import time

import numpy as np
import pytest
import torch

from dsage_ray.core.evaluation import SLICE, InProcessEvaluator, PendingEvaluation, evaluate_prefix
from tests.fakes import BitmapDomain


class ThreadRecordingDomain(BitmapDomain):
    """Records torch's intra-op thread count at each evaluation."""

    def __init__(self) -> None:
        super().__init__()
        self.threads: list[int] = []

    def evaluate(self, solution, seed):
        self.threads.append(torch.get_num_threads())
        return super().evaluate(solution, seed)


def test_threads_pins_torch_during_the_evaluations_and_restores_the_callers_count():
    domain = ThreadRecordingDomain()
    solutions = domain.random_solutions(3, np.random.default_rng(0))
    before = torch.get_num_threads()
    try:
        torch.set_num_threads(2)
        results = InProcessEvaluator(domain=domain, threads=1)(solutions, [0, 1, 2])
        assert domain.threads == [1, 1, 1] and torch.get_num_threads() == 2
        assert len(results) == 3 and not any(r.failed for r in results)
        InProcessEvaluator(domain=domain)(solutions[:1], [0])
        assert domain.threads[-1] == 2  # None leaves the process's count
    finally:
        torch.set_num_threads(before)


class ElsewhereEvaluator:
    """Stands in for the Ray pool: evaluates in this process, but says its simulators run elsewhere."""

    runs_elsewhere = True

    def __init__(self, domain, *, release: threading.Event | None = None, error: Exception | None = None) -> None:
        self.inner = InProcessEvaluator(domain=domain)
        self.release = release
        self.error = error
        self.threads: list[str] = []

    def __call__(self, solutions, seeds):
        self.threads.append(threading.current_thread().name)
        if self.release is not None:
            assert self.release.wait(10)
        if self.error is not None:
            raise self.error
        return self.inner(solutions, seeds)


def test_a_batch_for_simulators_elsewhere_runs_while_the_caller_works():
    domain = BitmapDomain()
    solutions = domain.random_solutions(4, np.random.default_rng(0))
    release = threading.Event()
    evaluator = ElsewhereEvaluator(domain, release=release)
    pending = PendingEvaluation(evaluator, solutions, [0, 1, 2, 3])
    assert pending.overlapped
    release.set()  # the batch was submitted before result() was asked for, or this would deadlock
    results = pending.result()
    assert evaluator.threads == ["dsage-evaluate"]
    expected = InProcessEvaluator(domain=domain)(solutions, [0, 1, 2, 3])
    assert [r.measures.tolist() for r in results] == [r.measures.tolist() for r in expected]


def test_an_in_process_batch_runs_when_its_result_is_asked_for():
    domain = ThreadRecordingDomain()
    pending = PendingEvaluation(InProcessEvaluator(domain=domain), domain.random_solutions(2, np.random.default_rng(0)),
                                [0, 1])
    assert not pending.overlapped and domain.threads == []
    assert len(pending.result()) == 2 and len(domain.threads) == 2


def test_what_the_background_evaluator_raises_is_raised_by_result():
    domain = BitmapDomain()
    pending = PendingEvaluation(ElsewhereEvaluator(domain, error=ValueError("simulator gone")),
                                domain.random_solutions(2, np.random.default_rng(0)), [0, 1])
    with pytest.raises(ValueError, match="simulator gone"):
        pending.result()


def test_a_passed_deadline_stops_a_batch_after_its_first_part_and_keeps_the_order():
    domain = BitmapDomain()
    solutions = domain.random_solutions(20, np.random.default_rng(0))
    seeds = list(range(20))
    expected = InProcessEvaluator(domain=domain)(solutions, seeds)
    passed = time.perf_counter() - 1.0
    counts: list[int] = []
    # The in-process evaluator stops itself after the level under way; a plain callable is cut in slices.
    in_process = evaluate_prefix(InProcessEvaluator(domain=domain), solutions, seeds, deadline=passed,
                                 progress=counts.append)
    plain = evaluate_prefix(lambda s, k: InProcessEvaluator(domain=domain)(s, k), solutions, seeds, deadline=passed)
    assert len(in_process) == 1 and counts == [1]
    assert len(plain) == SLICE
    for results in (in_process, plain):
        assert [r.measures.tolist() for r in results] == [r.measures.tolist() for r in expected[:len(results)]]
    # Without a deadline, all of it, with a count after each part.
    counts.clear()
    full = evaluate_prefix(lambda s, k: InProcessEvaluator(domain=domain)(s, k), solutions, seeds,
                           progress=counts.append)
    assert len(full) == 20 and counts == [8, 16, 20]
