"""An RLlib callback (new API stack) that audits the policy while it trains.

Every ``audit_every`` training iterations :class:`AuditCallback` saves the current RLModule as a
module-only checkpoint in ``<out_dir>/checkpoints/iter_<N>`` (what ``rllib:PATH`` loads) and audits it
with an :class:`~dsage_ray.audit.series.AuditSeries` in ``<out_dir>/audit_series``: the regression suite (every level
earlier audits found) is re-evaluated, then a short DSAGE search, warm-started from the previous audit's
surrogate, looks for new failures, which join the suite. The record's scalars land in the iteration's
result under ``"audit"`` (``result["audit"]["suite_success_rate"]``, ...), so Tune's and RLlib's loggers
see them, and in a TensorBoard writer, if given, as ``audit/...`` with step = environment steps sampled
so far.

Whatever goes wrong in an audit — an unreadable checkpoint, a dead actor, a bug — logs one warning
(``audit of iter_N skipped: <reason>``) and training goes on.

RLlib builds its callbacks itself (``config.callbacks(callbacks_class=...)`` takes any callable that
returns one), on the algorithm and on every env runner. :meth:`AuditCallback.configured` returns such a
callable with the settings bound::

    from dsage_ray.integrations.rllib import AuditCallback, finish_audits

    config = PPOConfig()....callbacks(AuditCallback.configured(audit_every=25, audit_budget=30,
                                                               out_dir="tb_logs/my_run"))
    algo = config.build_algo()
    for _ in range(100):
        result = algo.train()          # result["audit"]: the numbers of an audit that just ended
    finish_audits(algo)                # waits for the last audit

Only the algorithm's instance audits (``on_train_result`` runs in the algorithm's process); the env
runners' copies do nothing. By default the audits run in the background, in a Ray actor with one CPU of its
own: training waits only for the module to be saved, and an audit's numbers arrive a few iterations later
(at the step of the checkpoint they belong to). One audit runs at a time; one that falls due while another
runs is skipped, with a warning. ``background=False`` audits in the training process, between iterations
(``benchmarks/bench_audit_callback.py`` measures both). Call :func:`finish_audits` (or the callback's
``finish``) after the last iteration to wait for the last audit.
"""

from __future__ import annotations

import os
import time
from pathlib import Path
from typing import Any, Mapping

from ray.rllib.callbacks.callbacks import RLlibCallback

from dsage_ray.integrations.auditor import SeriesAuditor, finite_scalars
from dsage_ray.integrations.defaults import (DEFAULT_AUDIT_BUDGET, DEFAULT_AUDIT_EVERY, DEFAULT_EPISODES,
                                             DEFAULT_PRESET, SERIES_SUBDIR)

#: Result keys of the environment steps sampled so far, in the order they are tried.
_STEP_KEYS = (("env_runners", "num_env_steps_sampled_lifetime"), ("num_env_steps_sampled_lifetime",),
              ("timesteps_total",))


def env_steps(result: Mapping[str, Any]) -> int | None:
    """Environment steps sampled over the algorithm's lifetime, from a training result; None if absent."""
    for keys in _STEP_KEYS:
        value: Any = result
        for key in keys:
            value = value.get(key) if isinstance(value, Mapping) else None
        if value is not None:
            try:
                return int(value)
            except (TypeError, ValueError):
                continue
    return None


def save_module(algorithm: Any, path: str | os.PathLike[str], *, policy: str = "default_policy") -> Path:
    """Writes ``policy``'s RLModule as a module-only checkpoint to ``path`` (replaced if it exists).

    The module comes from the algorithm's local env runner (``algorithm.get_module``), which holds the
    weights the last update synced to it; with no local env runner, from the learner group.
    """
    import shutil

    path = Path(path).resolve()  # RLlib reads relative paths as URIs
    if path.exists():
        shutil.rmtree(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    module = algorithm.get_module(policy)
    if module is not None:
        module.save_to_path(str(path))
        return path
    results = algorithm.learner_group.foreach_learner(
        lambda learner: learner.module[policy].save_to_path(str(path)))
    for result in results:
        if not result.ok:
            raise result.get()
    return path


class AuditCallback(RLlibCallback):
    """Audits the training policy every ``audit_every`` iterations (module docstring).

    Args:
        audit_every: Training iterations between audits (iterations ``audit_every``, ``2·audit_every``, ...).
        out_dir: Module checkpoints go to ``out_dir/checkpoints/iter_<N>``, the audit series to
            ``out_dir/audit_series`` (continued if it exists).
        series_dir: Another folder for the series (one of ``out_dir`` and ``series_dir`` is required).
        audit_budget: Real evaluations of each audit's search.
        policy: The module to audit.
        writer: A TensorBoard ``SummaryWriter`` (or a folder to open one on) that also gets the scalars,
            step = environment steps. Objects that cannot be pickled are not sent to remote processes
            (an algorithm run by Tune on an actor gets None): pass a folder there.
        series: A factory of audit series (a class or function called with the ``AuditSeries`` keyword
            arguments), or a series object (``audit(spec, label=, step=)``, audited in this process);
            default :class:`~dsage_ray.audit.series.AuditSeries`, built at the first audit.
        **series_settings: ``background`` (default: audits in a Ray actor of their own, unless ``series``
            is an object), ``audit_cpus``, and the series' ``preset``, ``domain``, ``seed``, ``overrides``,
            ``local``, ``workers``, ``address``, ``episodes``, ``warm_start``
            (:class:`~dsage_ray.integrations.auditor.SeriesAuditor`).

    Background audits report when they end: their scalars go into the result of the iteration that sees
    them end (``result["audit"]``, with ``checkpoint_iteration``, the iteration audited) and to the writer at
    the audited checkpoint's env steps. :meth:`finish` (or :func:`finish_audits`) waits for the last one.
    """

    def __init__(
        self,
        *,
        audit_every: int = DEFAULT_AUDIT_EVERY,
        out_dir: str | os.PathLike[str] | None = None,
        series_dir: str | os.PathLike[str] | None = None,
        audit_budget: int = DEFAULT_AUDIT_BUDGET,
        policy: str = "default_policy",
        writer: Any = None,
        series: Any = None,
        **series_settings: Any,
    ) -> None:
        super().__init__()
        if int(audit_every) < 1:
            raise ValueError(f"audit_every must be at least 1, got {audit_every}")
        if out_dir is None and series_dir is None:
            raise ValueError("AuditCallback needs out_dir (or series_dir)")
        series_settings.setdefault("preset", DEFAULT_PRESET)
        series_settings.setdefault("episodes", DEFAULT_EPISODES)
        self.audit_every = int(audit_every)
        self.policy = policy
        self.out_dir = Path(out_dir) if out_dir is not None else None
        if series_dir is None:
            series_dir = (self.out_dir or Path(".")) / SERIES_SUBDIR
        self.auditor = SeriesAuditor(out_dir=series_dir, series=series, writer=writer,
                                     audit_budget=audit_budget, **series_settings)
        #: ``(iteration, record or None, seconds)`` of every audit that ended (seconds: how long training waited
        #: for it: saving the module, and in this process the audit itself).
        self.audits: list[tuple[int, Any, float]] = []
        self._waited: dict[str, float] = {}

    @classmethod
    def configured(cls, **settings: Any) -> "ConfiguredAuditCallback":
        """A callable RLlib's ``config.callbacks(...)`` accepts, that builds this callback with ``settings``.

        The settings are checked here, so a bad one fails when the config is written, not in RLlib's setup.
        """
        cls(**settings)  # validates the arguments (the series is built at the first audit, not here)
        return ConfiguredAuditCallback(cls, settings)

    def checkpoint_dir(self, iteration: int) -> Path:
        """Where the module of ``iteration`` is saved."""
        return (self.out_dir or Path(".")) / "checkpoints" / f"iter_{iteration}"

    def on_train_result(self, *, algorithm: Any, metrics_logger: Any = None, result: dict, **kwargs: Any) -> None:
        iteration = result.get("training_iteration")
        iteration = int(iteration) if iteration is not None else int(getattr(algorithm, "iteration", 0))
        finished = self.auditor.poll() if self.auditor.background else []
        if iteration > 0 and iteration % self.audit_every == 0:
            label = f"iter_{iteration}"

            def spec() -> str:
                return f"rllib:{save_module(algorithm, self.checkpoint_dir(iteration), policy=self.policy)}"

            started = time.perf_counter()
            finished += self.auditor.submit(spec, label=label, step=env_steps(result))
            self._waited[label] = time.perf_counter() - started
        self._record(finished, result)

    def finish(self, timeout: float | None = None) -> list[tuple[int, Any, float]]:
        """Waits for a background audit still running (up to ``timeout`` s); the audits that ended here."""
        finished = self.auditor.finish(timeout=timeout)
        self._record(finished, None)
        return self.audits[len(self.audits) - len(finished):] if finished else []

    def _record(self, finished: list, result: dict | None) -> None:
        for audit in finished:
            self.audits.append((int(audit.label.removeprefix("iter_")), audit.record, self._waited.pop(audit.label, 0.0)))
            if audit.record is None or result is None:
                continue
            try:
                numbers = {tag.removeprefix("audit/"): value for tag, value in finite_scalars(audit.record).items()}
            except Exception:  # noqa: BLE001 - already warned about by the auditor
                continue
            result["audit"] = {**numbers, "checkpoint_iteration": int(audit.label.removeprefix("iter_"))}


def finish_audits(algorithm: Any, timeout: float | None = None) -> list[tuple[int, Any, float]]:
    """Waits for the background audits of ``algorithm``'s :class:`AuditCallback` s; the audits that ended."""
    callbacks = algorithm.callbacks if isinstance(algorithm.callbacks, (list, tuple)) else [algorithm.callbacks]
    return [audit for callback in callbacks if isinstance(callback, AuditCallback)
            for audit in callback.finish(timeout=timeout)]


class ConfiguredAuditCallback:
    """``AuditCallback`` with its settings bound: what :meth:`AuditCallback.configured` returns.

    Calling it builds the callback. Copies (RLlib deep-copies its config) share the settings' objects
    (the writer, the series); pickling drops a writer or series that cannot be pickled (for remote env
    runners, which never audit).
    """

    def __init__(self, cls: type, settings: Mapping[str, Any]) -> None:
        self.cls = cls
        self.settings = dict(settings)

    def __call__(self) -> AuditCallback:
        return self.cls(**self.settings)

    def __deepcopy__(self, memo: dict) -> "ConfiguredAuditCallback":
        return ConfiguredAuditCallback(self.cls, self.settings)

    def __reduce__(self):
        from ray import cloudpickle

        settings = {}
        for key, value in self.settings.items():
            try:
                cloudpickle.dumps(value)
            except Exception:  # noqa: BLE001 - writers hold threads and files
                if key == "series":  # a series object that stays here: the copy cannot audit
                    value, settings["background"] = _NoSeries(), False
                else:
                    value = None
            settings[key] = value
        return (ConfiguredAuditCallback, (self.cls, settings))

    def __repr__(self) -> str:
        shown = ", ".join(f"{k}={v!r}" for k, v in self.settings.items() if k not in ("writer", "series"))
        return f"{self.cls.__name__}.configured({shown})"


class _NoSeries:
    """Stands in for a series that could not travel; an audit with it fails (and says so)."""

    def audit(self, spec: str, *, label: str | None = None, step: int | None = None) -> Any:
        raise RuntimeError("no audit series in this process (the series object could not be pickled)")
