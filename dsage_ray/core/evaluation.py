"""Real evaluations: an in-process evaluator and the retry policy every evaluator shares."""

from __future__ import annotations

import logging
import traceback
from typing import Sequence

import numpy as np

from dsage_ray.core.threads import torch_threads
from dsage_ray.types import Domain, EvaluationResult, Evaluator, Solutions

logger = logging.getLogger(__name__)


class InProcessEvaluator:
    """Evaluates solutions one after another in this process.

    The Ray simulator pool implements the same call signature; the algorithm never knows which
    one it has.

    Args:
        domain: Builds levels and simulates the agent.
        threads: Torch intra-op threads while evaluating (a run's ``torch_threads``); None leaves the
            process's count. Torch's default, one thread per core, makes an agent's small per-step batches
            several times slower when other processes share the cores (measured: 2.7 s instead of 0.6 s per
            50-episode Maze level beside another audit).
    """

    def __init__(self, *, domain: Domain, threads: int | None = None) -> None:
        self.domain = domain
        self.threads = threads

    def __call__(self, solutions: Solutions, seeds: Sequence[int]) -> list[EvaluationResult]:
        if self.threads is None:
            return self._evaluate(solutions, seeds)
        with torch_threads(self.threads):
            return self._evaluate(solutions, seeds)

    def _evaluate(self, solutions: Solutions, seeds: Sequence[int]) -> list[EvaluationResult]:
        return [evaluate_safely(self.domain, solution, int(seed)) for solution, seed in zip(solutions, seeds)]


def evaluate_safely(domain: Domain, solution: np.ndarray, seed: int) -> EvaluationResult:
    """``domain.evaluate`` with any exception turned into a failed result that carries the error."""
    try:
        return domain.evaluate(solution, seed)
    except Exception as exc:  # noqa: BLE001 - a simulator may raise anything; the run must go on.
        logger.debug("evaluation failed:\n%s", traceback.format_exc())
        return EvaluationResult.failure(
            error=f"{type(exc).__name__}: {exc}",
            num_measures=len(domain.measure_names),
            occupancy_shape=domain.occupancy_shape,
        )


def evaluate_with_retry(evaluator: Evaluator, solutions: Solutions, seeds: Sequence[int]) -> list[EvaluationResult]:
    """Evaluates a batch, then re-submits each failed evaluation exactly once.

    A result that fails twice is returned as failed (with its error), so the caller can record it;
    nothing is dropped and nothing is evaluated more than twice.
    """
    results = list(evaluator(solutions, seeds))
    if len(results) != len(solutions):
        raise RuntimeError(f"evaluator returned {len(results)} results for {len(solutions)} solutions")
    failed = [i for i, r in enumerate(results) if r.failed]
    if failed:
        logger.warning("%d evaluation(s) failed; retrying once: %s", len(failed), results[failed[0]].error)
        retried = evaluator(solutions[failed], [seeds[i] for i in failed])
        for i, result in zip(failed, retried):
            results[i] = result
    return results
