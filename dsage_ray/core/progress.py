"""One progress line per outer iteration, shared by local runs and Tune trials.

``iter 3/~12  evals 400/2000  qd_score 812.0  coverage 0.031  elapsed 2m10s  ETA 6m30s``
"""

from __future__ import annotations

import math
import threading
from typing import Mapping


def format_duration(seconds: float) -> str:
    """``42s``, ``2m10s`` or ``1h05m``: short enough for a progress line."""
    if not math.isfinite(seconds):
        return "?"
    seconds = max(0, round(seconds))
    if seconds < 60:
        return f"{seconds}s"
    minutes, seconds = divmod(seconds, 60)
    if minutes < 60:
        return f"{minutes}m{seconds:02d}s"
    hours, minutes = divmod(minutes, 60)
    return f"{hours}h{minutes:02d}m"


def progress_line(metrics: Mapping[str, float], *, budget: int, elapsed_s: float, evals_per_s: float,
                  time_budget: float = 0.0) -> str:
    """The progress line of one outer iteration.

    The iteration total is an estimate (``~``): later iterations are assumed to evaluate as many
    levels as the last one, which holds once the random initial batch is past. When the time budget
    will end the run first, the line says so (``ETA 4m10s (time budget)``) and the total counts the
    iterations that fit in the time left at the evaluation rate so far.

    Args:
        metrics: The runner's metrics of the iteration just finished (``outer_iteration``, ``evals``,
            ``evaluated_this_iteration``, ``qd_score``, ``coverage``; ``wall_time``, what the time budget
            counts, else ``elapsed_s`` stands for it).
        budget: The run's evaluation budget.
        elapsed_s: Wall time shown as ``elapsed``.
        evals_per_s: Evaluation rate so far; the ETA is the remaining budget at this rate.
        time_budget: The run's ``time_budget`` in seconds (0: none).
    """
    iteration = int(metrics["outer_iteration"])
    evals = int(metrics["evals"])
    remaining = max(budget - evals, 0)
    time_left = (time_budget - float(metrics.get("wall_time", elapsed_s))) if time_budget > 0 else math.inf
    eval_eta = remaining / evals_per_s if evals_per_s > 0 else math.inf
    per_iteration = max(int(metrics.get("evaluated_this_iteration", 0)), 1)
    if remaining == 0 or time_left <= 0:
        iterations, eta = f"{iteration}", "done"
    elif time_left < eval_eta:
        # The run ends when the time runs out, inside the iteration under way.
        iterations = f"~{iteration + math.ceil(time_left * evals_per_s / per_iteration)}"
        eta = f"{format_duration(time_left)} (time budget)"
    else:
        iterations = f"~{iteration + math.ceil(remaining / per_iteration)}"
        eta = format_duration(eval_eta)
    return (f"iter {iteration}/{iterations}  evals {evals}/{budget}  qd_score {metrics['qd_score']:.1f}  "
            f"coverage {metrics['coverage']:.3f}  elapsed {format_duration(elapsed_s)}  ETA {eta}")


class EvaluationRate:
    """Evaluations per second of one run, measured from the first iteration seen.

    The first iteration evaluates random levels without training a surrogate, so it is far cheaper
    per evaluation than the rest; once a later iteration is seen, the rate counts only what came
    after the first one, so the ETA does not promise a DSAGE run the speed of its random start.
    """

    def __init__(self) -> None:
        self._first: tuple[float, float] | None = None

    def update(self, *, evals: float, running_s: float) -> float:
        """The rate after an iteration that ended at ``evals`` after ``running_s`` of running time."""
        if self._first is None:
            self._first = (evals, running_s)
            return evals / running_s if running_s > 0 else 0.0
        first_evals, first_s = self._first
        return (evals - first_evals) / (running_s - first_s) if running_s > first_s else 0.0


class ConsoleProgress:
    """Progress on the terminal for a run in this process: a bar per phase and a line per outer iteration.

    Pass :meth:`phase` as the runner's ``progress`` callback and the object itself as a
    :class:`~dsage_ray.core.loop.RunLoop` callback.

    Args:
        budget: The run's evaluation budget (for the ETA).
        time_budget: The run's time budget in seconds, 0 for none (for the ETA).
    """

    def __init__(self, *, budget: int, time_budget: float = 0.0) -> None:
        self.budget = budget
        self.time_budget = time_budget
        self._bars: dict = {}
        self._lock = threading.Lock()
        self._started: float | None = None
        self._evals_at_start = 0
        self._rate = EvaluationRate()

    def phase(self, phase: str, done: int, total: int) -> None:
        """The runner's progress callback: moves the bar of ``phase`` (a new bar when a new pass starts).

        Thread-safe: a pipelined run's evaluation reports from its own thread while the inner loop reports.
        """
        with self._lock:
            self._move(phase, done, total)

    def _move(self, phase: str, done: int, total: int) -> None:
        from tqdm import tqdm

        bar = self._bars.get(phase)
        if bar is None or bar.total != total or done < bar.n:
            if bar is not None:
                bar.close()
            bar = self._bars[phase] = tqdm(total=total, desc=phase, leave=phase == "evaluate", dynamic_ncols=True)
        bar.update(done - bar.n)
        if done >= total and phase != "evaluate":
            # A finished pass (held-out levels, one inner loop) leaves the screen; an open bar would
            # be redrawn under every later line with its clock still running.
            bar.close()
            del self._bars[phase]

    def on_start(self, run) -> None:
        """Starts the clock; a resumed run's ETA counts only the evaluations made since."""
        import time

        self._started, self._evals_at_start = time.monotonic(), run.evals

    def on_step(self, run, metrics: Mapping[str, float]) -> None:
        import time

        from tqdm import tqdm

        if self._started is None:
            self.on_start(run)
        elapsed = time.monotonic() - self._started
        evals_per_s = self._rate.update(evals=run.evals - self._evals_at_start, running_s=elapsed)
        tqdm.write(progress_line(metrics, budget=self.budget, elapsed_s=elapsed, evals_per_s=evals_per_s,
                                 time_budget=self.time_budget))
        from dsage_ray.core.auto_search import SearchChoice, direct_variant

        choice = SearchChoice.from_metrics(metrics, variant=direct_variant(run.config))
        if choice is not None:  # ``search = "auto"`` chose in this iteration
            tqdm.write(choice.reason)

    def close(self) -> None:
        for bar in self._bars.values():
            bar.close()
        self._bars.clear()
