"""Real evaluations: an in-process evaluator, the retry policy every evaluator shares, and evaluations
that run while the driver does something else."""

from __future__ import annotations

import logging
import threading
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


class PendingEvaluation:
    """A batch's evaluation (with :func:`evaluate_with_retry`), started now and collected by :meth:`result`.

    An evaluator whose simulators run in other processes says so with a true ``runs_elsewhere``
    attribute (the Ray pool does); its batch is then submitted from a background thread at once, and
    the caller's own work overlaps it. Any other evaluator (the in-process one shares the caller's
    CPU and torch's thread settings) runs inside :meth:`result`, after the caller's work. The results
    are the same either way: an evaluation's seed is fixed by its index, never by when it runs.

    The thread is a daemon, so an interrupted run exits without waiting for the batch; its
    evaluations are lost with the rest of the unfinished outer iteration, and a resume redoes it.
    """

    def __init__(self, evaluator: Evaluator, solutions: Solutions, seeds: Sequence[int]) -> None:
        self._call = (evaluator, solutions, list(seeds))
        self._results: list[EvaluationResult] | None = None
        self._error: BaseException | None = None
        self._thread: threading.Thread | None = None
        if getattr(evaluator, "runs_elsewhere", False) and len(solutions):
            self._thread = threading.Thread(target=self._run, name="dsage-evaluate", daemon=True)
            self._thread.start()

    @property
    def overlapped(self) -> bool:
        """Whether the batch is being evaluated in the background while the caller works."""
        return self._thread is not None

    def _run(self) -> None:
        try:
            self._results = evaluate_with_retry(*self._call)
        except BaseException as exc:  # noqa: BLE001 - re-raised in the caller's thread by result()
            self._error = exc

    def result(self) -> list[EvaluationResult]:
        """Waits for (or runs) the evaluation; re-raises what the evaluator raised."""
        if self._thread is None:
            self._run()
        else:
            self._thread.join()
        if self._error is not None:
            raise self._error
        assert self._results is not None
        return self._results
