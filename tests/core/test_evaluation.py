"""``InProcessEvaluator``: evaluations in this process, on the run's torch threads when it is given them."""

import numpy as np
import torch

from dsage_ray.core.evaluation import InProcessEvaluator
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
