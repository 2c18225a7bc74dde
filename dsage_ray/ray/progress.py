"""What a Tune run prints: one progress line per trial result, Tune's own tables and hints kept quiet.

Tune's new console output (Ray 2.60) prints a status table every few seconds and, at the start, a
``tensorboard --logdir /tmp/ray/session_…`` hint pointing at the driver's staging copy, which holds
Tune's scalars but none of the trial's images. That hint is printed whenever the new output engine
runs, even at ``verbose=0``; the legacy engine (``RAY_AIR_NEW_OUTPUT=0``) has no such hint, and at
``verbose=0`` prints nothing but errors, which Tune logs through ``logging`` either way.
"""

from __future__ import annotations

import contextlib
import os
import sys
import time
from typing import Any, Iterator

from ray import tune

from dsage_ray.core.auto_search import SearchChoice
from dsage_ray.core.progress import EvaluationRate, progress_line
from dsage_ray.domains.registry import DEFAULT_DOMAIN, get_domain

#: Set for the duration of a Tune run unless the user set them: the legacy console engine (no
#: misleading TensorBoard hint), no warning about frequent experiment snapshots, which
#: ``checkpoint_frequency=1`` causes on purpose (a crashed trial loses at most one iteration), and
#: none of the loggers Tune adds by itself: its TensorBoard logger would copy every result as a
#: ``ray/tune/*`` scalar against the iteration beside our ``dsage/*`` ones against evaluations, so
#: :func:`~dsage_ray.ray.experiment.run_experiment` passes the CSV and JSON loggers it keeps.
_QUIET_TUNE_ENV = {
    "RAY_AIR_NEW_OUTPUT": "0",
    "TUNE_WARN_EXCESSIVE_EXPERIMENT_CHECKPOINT_SYNC_THRESHOLD_S": "0",
    "TUNE_DISABLE_AUTO_CALLBACK_LOGGERS": "1",
}


@contextlib.contextmanager
def quiet_tune_output() -> Iterator[None]:
    """Within the block, Tune runs with :data:`_QUIET_TUNE_ENV` (variables the user set win).

    Tune reads both variables in the driver when ``tune.run`` / ``Tuner.fit`` starts, so setting
    them only around the call leaves the rest of the process untouched.
    """
    added = {key: value for key, value in _QUIET_TUNE_ENV.items() if key not in os.environ}
    os.environ.update(added)
    try:
        yield
    finally:
        for key in added:
            os.environ.pop(key, None)


class ProgressLines(tune.Callback):
    """Prints :func:`~dsage_ray.core.progress.progress_line` for every trial result, in the driver.

    The ETA uses the trial's own evaluation rate against its running time (``time_total_s``, carried
    over a restore), so trials waiting for CPUs do not distort it. With several trials each
    line starts with the trial's grid values (``variant=dsage seed=1``) and ends with how many
    trials have finished. Trial failures get a line too (Tune logs their tracebacks).
    """

    def __init__(self) -> None:
        self._started = time.monotonic()
        self._rates: dict[str, EvaluationRate] = {}
        self._finished: set[str] = set()

    def setup(self, **info: Any) -> None:
        # Called by every tune.run / Tuner.fit, a resumed one included.
        self._started = time.monotonic()
        self._rates = {}
        self._finished = set()

    def on_trial_result(self, iteration: int, trials: list, trial, result: dict, **info: Any) -> None:
        if "outer_iteration" not in result:
            return
        evals = float(result["evals"])
        rate = self._rates.setdefault(trial.trial_id, EvaluationRate()).update(
            evals=evals, running_s=float(result.get("time_total_s") or 0.0))
        line = progress_line(result, budget=int(result.get("budget", evals)),
                             elapsed_s=time.monotonic() - self._started, evals_per_s=rate,
                             time_budget=float(result.get("time_budget", 0.0)))
        if result.get("done"):
            self._finished.add(trial.trial_id)
        if len(trials) > 1:
            # A trial stays RUNNING while Tune hands out its last result, and may still be RUNNING
            # when another trial's last result arrives, so the callback remembers who said done.
            finished = len(self._finished | {other.trial_id for other in trials if other.status == "TERMINATED"})
            line = f"{_label(trial)}  {line}  trials done {finished}/{len(trials)}"
        _print(line)
        choice = SearchChoice.from_metrics(result, variant=_direct_search(trial))
        if choice is not None:
            _print(f"{_label(trial)}: {choice.reason}" if len(trials) > 1 else choice.reason)

    def on_trial_recover(self, iteration: int, trials: list, trial, **info: Any) -> None:
        _print(f"{_label(trial)}: failed; Tune restarts it from its last checkpoint")

    def on_trial_error(self, iteration: int, trials: list, trial, **info: Any) -> None:
        _print(f"{_label(trial)}: failed for good; details in {trial.error_file}")


def _direct_search(trial) -> str:
    """The direct search of the trial's domain (what ``search = "auto"`` may continue with)."""
    config = getattr(trial, "config", None) or {}
    return get_domain(config.get("domain", DEFAULT_DOMAIN)).direct_search


def _label(trial) -> str:
    """``variant=dsage seed=1`` for a grid trial, else Tune's trial name."""
    params = getattr(trial, "evaluated_params", None) or {}
    return " ".join(f"{key}={value}" for key, value in params.items()) or str(trial)


def _print(line: str) -> None:
    print(line, file=sys.stdout, flush=True)
