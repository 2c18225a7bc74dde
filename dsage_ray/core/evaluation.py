"""Real evaluations: an in-process evaluator, the retry policy every evaluator shares, and evaluations
that run while the driver does something else."""

from __future__ import annotations

import contextlib
import logging
import threading
import time
import traceback
from typing import Callable, Sequence

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
        return self.evaluate_until(solutions, seeds)

    def evaluate_until(self, solutions: Solutions, seeds: Sequence[int], *, deadline: float | None = None,
                       progress: "EvaluationProgress | None" = None) -> list[EvaluationResult]:
        """Evaluates in order, one level at a time, until the batch is done or ``deadline`` (perf_counter) has
        passed (at least one level); ``progress`` hears the count after each."""
        results: list[EvaluationResult] = []
        with torch_threads(self.threads) if self.threads is not None else contextlib.nullcontext():
            for solution, seed in zip(solutions, seeds):
                if results and deadline is not None and time.perf_counter() >= deadline:
                    break
                results.append(evaluate_safely(self.domain, solution, int(seed)))
                if progress is not None:
                    progress(len(results))
        return results


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


#: Called with the number of a batch's evaluations done so far.
EvaluationProgress = Callable[[int], None]
#: Solutions per call when an evaluator without :meth:`~InProcessEvaluator.evaluate_until` is given a
#: deadline or a progress callback: often enough to stop near the deadline and to move a progress bar.
SLICE = 8


def evaluate_prefix(evaluator: Evaluator, solutions: Solutions, seeds: Sequence[int], *,
                    deadline: float | None = None, progress: EvaluationProgress | None = None
                    ) -> list[EvaluationResult]:
    """Evaluates the batch, or with a ``deadline`` (a :func:`time.perf_counter` value) the part of it begun before then.

    What comes back is always a prefix of the batch in order (at least one result when the batch is not
    empty), so that evaluation ``i`` keeps seed ``seeds[i]`` whoever stops where. An evaluator with an
    ``evaluate_until(solutions, seeds, *, deadline, progress)`` method (the in-process evaluator, the Ray
    pool) stops itself, letting the levels under way finish; any other is called in slices of :data:`SLICE`.
    """
    native = getattr(evaluator, "evaluate_until", None)
    if native is not None:
        results = list(native(solutions, seeds, deadline=deadline, progress=progress))
        if not 0 < len(results) <= len(solutions) and len(solutions):
            raise RuntimeError(f"evaluator returned {len(results)} results for {len(solutions)} solutions")
        return results
    size = len(solutions) if deadline is None and progress is None else SLICE
    results: list[EvaluationResult] = []
    for start in range(0, len(solutions), max(size, 1)):
        if results and deadline is not None and time.perf_counter() >= deadline:
            break
        part = list(evaluator(solutions[start:start + size], list(seeds[start:start + size])))
        if len(part) != len(solutions[start:start + size]):
            raise RuntimeError(f"evaluator returned {len(part)} results for {len(solutions[start:start + size])} "
                               "solutions")
        results += part
        if progress is not None:
            progress(len(results))
    return results


def evaluate_with_retry(evaluator: Evaluator, solutions: Solutions, seeds: Sequence[int], *,
                        deadline: float | None = None, progress: EvaluationProgress | None = None
                        ) -> list[EvaluationResult]:
    """Evaluates a batch (:func:`evaluate_prefix`: all of it unless a ``deadline`` stops it early), then
    re-submits each failed evaluation exactly once.

    A result that fails twice is returned as failed (with its error), so the caller can record it;
    nothing is dropped and nothing is evaluated more than twice.
    """
    results = evaluate_prefix(evaluator, solutions, seeds, deadline=deadline, progress=progress)
    failed = [i for i, r in enumerate(results) if r.failed]
    if failed:
        logger.warning("%d evaluation(s) failed; retrying once: %s", len(failed), results[failed[0]].error)
        retried = evaluator(solutions[failed], [seeds[i] for i in failed])
        for i, result in zip(failed, retried):
            results[i] = result
    return results


class PendingEvaluation:
    """A batch's evaluation (with :func:`evaluate_with_retry`), started now and collected by :meth:`result`.

    With a ``deadline`` the result may be a prefix of the batch (:func:`evaluate_prefix`).

    An evaluator whose simulators run in other processes says so with a true ``runs_elsewhere``
    attribute (the Ray pool does); its batch is then submitted from a background thread at once, and
    the caller's own work overlaps it. Any other evaluator (the in-process one shares the caller's
    CPU and torch's thread settings) runs inside :meth:`result`, after the caller's work. The results
    are the same either way: an evaluation's seed is fixed by its index, never by when it runs.

    The thread is a daemon, so an interrupted run exits without waiting for the batch; its
    evaluations are lost with the rest of the unfinished outer iteration, and a resume redoes it.
    """

    def __init__(self, evaluator: Evaluator, solutions: Solutions, seeds: Sequence[int], *,
                 deadline: float | None = None, progress: EvaluationProgress | None = None) -> None:
        self._call = (evaluator, solutions, list(seeds))
        self._options = {"deadline": deadline, "progress": progress}
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
            self._results = evaluate_with_retry(*self._call, **self._options)
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
