"""The auditor the callbacks share: the audit series, a TensorBoard writer, background audits and the fault rule."""

from __future__ import annotations

import contextlib
import dataclasses
import math
import os
from pathlib import Path
from typing import Any, Callable, Mapping

from dsage_ray.domains.registry import DEFAULT_DOMAIN
from dsage_ray.integrations.defaults import DEFAULT_AUDIT_BUDGET, DEFAULT_EPISODES, DEFAULT_OVERRIDES, DEFAULT_PRESET
from dsage_ray.integrations.faults import describe, log, one_warning
from dsage_ray.integrations.series_actor import SeriesActor, build_series


def finite_scalars(record: Any) -> dict[str, float]:
    """``record.scalars()`` without the values an incomplete audit leaves out (None, NaN)."""
    out = {}
    for tag, value in dict(record.scalars()).items():
        try:
            value = float(value)
        except (TypeError, ValueError):
            continue
        if math.isfinite(value):
            out[tag] = value
    return out


@dataclasses.dataclass(frozen=True)
class FinishedAudit:
    """An audit that ended: its label, its training step, its record (None when it raised) and when it ended."""

    label: str
    step: int | None
    record: Any


@dataclasses.dataclass
class _InFlight:
    label: str
    step: int | None
    ref: Any


class SeriesAuditor:
    """What the callbacks share: the audit series, a TensorBoard writer, background audits and the fault rule.

    Audits run in one of two ways:

    * **in the background** (``background=True``): the series lives in a Ray actor of its own
      (``audit_cpus`` CPUs, on this node, since it reads the checkpoints this process writes) and
      :meth:`submit` returns at once; :meth:`poll` collects an audit that has finished. Training waits only
      for the checkpoint to be written. One audit runs at a time: one that is due while another still
      runs is skipped (with a warning: audit less often). An actor that dies is replaced at the next audit
      and its series continues from ``series.json``;
    * **in this process** (``background=False``): :meth:`submit` runs the audit and returns it. The global
      random states (``random``, NumPy's, torch's, torch's thread count) are put back afterwards, so that
      the training samples what it would have without the audit.

    Args:
        out_dir: The series folder (``series.json``, one folder per audit); an existing series there is
            continued.
        series: None (an :class:`~dsage_ray.audit.series.AuditSeries` on ``out_dir`` with the settings
            below), a factory called with the ``AuditSeries`` keyword arguments that returns an object with
            ``audit(spec, label=, step=)`` (a class, a function; it must pickle for background audits),
            or such an object itself (audited in this process).
        writer: Where the audit's scalars also go: an object with ``add_scalar(tag, value, step)`` (a
            ``SummaryWriter``), a folder to open a ``tensorboardX.SummaryWriter`` on at the first audit,
            or None.
        background: Audit in a Ray actor (default: yes, unless ``series`` is an object).
        audit_cpus: CPUs the background actor reserves.
        audit_budget: Real evaluations of each audit's search.
        preset, domain, seed, overrides, local, workers, address, episodes, warm_start: The
            ``AuditSeries`` settings (``local``: the audit runs in its process, no further actors).
            ``overrides`` go over :data:`DEFAULT_OVERRIDES`.
    """

    def __init__(
        self,
        *,
        out_dir: str | os.PathLike[str],
        series: Any = None,
        writer: Any = None,
        background: bool | None = None,
        audit_cpus: float = 1.0,
        audit_budget: int = DEFAULT_AUDIT_BUDGET,
        preset: str | None = DEFAULT_PRESET,
        domain: str = DEFAULT_DOMAIN,
        seed: int = 0,
        overrides: Mapping[str, Any] | None = None,
        local: bool = True,
        workers: int | None = None,
        address: str | None = None,
        episodes: int | None = DEFAULT_EPISODES,
        warm_start: bool = True,
    ) -> None:
        if int(audit_budget) < 1:
            raise ValueError(f"audit_budget must be at least 1, got {audit_budget}")
        is_object = series is not None and not isinstance(series, type) and hasattr(series, "audit")
        self.background = (not is_object) if background is None else bool(background)
        if self.background and is_object:
            raise ValueError("background audits build their series in a Ray actor: pass a factory (a class or a "
                             "function), not a series object, or background=False")
        self.out_dir = Path(out_dir)
        self.audit_cpus = float(audit_cpus)
        self.series_kwargs = dict(out_dir=self.out_dir, domain=domain, preset=preset, budget=int(audit_budget),
                                  seed=seed, overrides={**DEFAULT_OVERRIDES, **dict(overrides or {})}, local=local,
                                  workers=workers, address=address, episodes=episodes, warm_start=warm_start)
        self._series = series
        self._series_built = is_object
        self._writer = writer
        self._actor: Any = None
        self._inflight: _InFlight | None = None

    # ------------------------------------------------------------------------------------ series

    @property
    def series(self) -> Any:
        """The series of in-process audits (built on first use, so that constructing a callback is cheap)."""
        if not self._series_built:
            self._series = build_series(self._series, self.series_kwargs)
            self._series_built = True
        return self._series

    @property
    def writer(self) -> Any:
        """The TensorBoard writer, opened on first use when given as a folder; None without one."""
        if isinstance(self._writer, (str, os.PathLike)):
            try:
                from tensorboardX import SummaryWriter
            except ImportError:  # pragma: no cover - tensorboardX is a dependency
                from torch.utils.tensorboard import SummaryWriter
            self._writer = SummaryWriter(str(self._writer))
        return self._writer

    @property
    def running(self) -> str | None:
        """The label of the background audit in flight, if any."""
        return None if self._inflight is None else self._inflight.label

    # ---------------------------------------------------------------------------------- auditing

    def submit(self, spec: str | Callable[[], str], *, label: str, step: int | None) -> list[FinishedAudit]:
        """Starts (background) or runs (in this process) the audit of ``spec``; the audits that ended meanwhile.

        ``spec`` may be a callable that produces the agent spec (e.g. by saving the checkpoint): what it
        raises counts as a failed audit too. Nothing is raised: a failed audit is one warning line
        (``audit of <label> skipped: <reason>``) and a :class:`FinishedAudit` whose record is None.
        """
        if not self.background:
            return [FinishedAudit(label, step, self.audit(spec, label=label, step=step))]
        finished = self.poll()
        if self._inflight is not None:
            log.warning("audit of %s skipped: the audit of %s is still running (or waiting for a CPU); audit less "
                        "often", label, self._inflight.label)
            return finished
        try:
            if callable(spec):
                spec = spec()
            ref = self._ensure_actor().audit.remote(spec, label, step)
        except Exception as exc:  # noqa: BLE001 - an audit must never stop training
            log.warning("audit of %s skipped: %s", label, describe(exc))
            return [*finished, FinishedAudit(label, step, None)]
        self._inflight = _InFlight(label, step, ref)
        return finished

    def poll(self, timeout: float | None = 0.0) -> list[FinishedAudit]:
        """The background audit, if it has ended (within ``timeout`` seconds; None: wait for it), reported."""
        if self._inflight is None:
            return []
        import ray

        ready, _ = ray.wait([self._inflight.ref], timeout=timeout)
        if not ready:
            return []
        inflight, self._inflight = self._inflight, None
        try:
            record = ray.get(inflight.ref)
        except Exception as exc:  # noqa: BLE001 - a dead actor, an error in the audit: never stop training
            if isinstance(exc, ray.exceptions.RayActorError):
                self._actor = None  # replaced at the next audit
            cause = getattr(exc, "cause", None)
            log.warning("audit of %s skipped: %s", inflight.label, describe(cause if cause is not None else exc))
            return [FinishedAudit(inflight.label, inflight.step, None)]
        self.report(record, label=inflight.label, step=inflight.step)
        return [FinishedAudit(inflight.label, inflight.step, record)]

    def finish(self, timeout: float | None = None) -> list[FinishedAudit]:
        """Waits for the background audit (up to ``timeout`` seconds), then ends the actor if none runs."""
        finished = self.poll(timeout=timeout)
        if self._inflight is not None:
            log.warning("audit of %s still running after %s s; left to finish in its actor", self._inflight.label,
                        timeout)
        elif self._actor is not None:
            import ray

            ray.kill(self._actor)
            self._actor = None
        return finished

    def audit(self, spec: str | Callable[[], str], *, label: str, step: int | None) -> Any:
        """Audits one checkpoint in this process; the series' record, or None when the audit raised.

        A record whose ``error`` is set logs the same one warning; its scalars that are numbers still go to
        the writer.
        """
        try:
            if callable(spec):
                spec = spec()
            with one_warning(), _global_rng_kept():
                record = self.series.audit(spec, label=label, step=step)
        except Exception as exc:  # noqa: BLE001 - an audit must never stop training
            log.warning("audit of %s skipped: %s", label, describe(exc))
            return None
        self.report(record, label=label, step=step)
        return record

    def report(self, record: Any, *, label: str, step: int | None) -> None:
        """Logs a record's error (one warning) and writes its numeric scalars."""
        if getattr(record, "error", None):
            reason = str(record.error).strip().splitlines()
            log.warning("audit of %s skipped: %s", label, reason[-1] if reason else "unknown error")
        try:
            self.write(finite_scalars(record), step)
        except Exception as exc:  # noqa: BLE001
            log.warning("audit of %s: scalars not written: %s", label, describe(exc))

    def write(self, scalars: Mapping[str, float], step: int | None) -> None:
        """Writes ``scalars`` (``audit/...`` tags) to the writer, if there is one, at ``step``."""
        writer = self.writer
        if writer is None or not scalars:
            return
        for tag, value in scalars.items():
            writer.add_scalar(tag, value, step)
        if hasattr(writer, "flush"):
            writer.flush()

    def _ensure_actor(self) -> Any:
        if self._actor is None:
            import ray
            from ray.util.scheduling_strategies import NodeAffinitySchedulingStrategy

            # On this node (the checkpoints are this process's files), outside any placement group of a trial.
            here = NodeAffinitySchedulingStrategy(node_id=ray.get_runtime_context().get_node_id(), soft=False)
            self._actor = ray.remote(SeriesActor).options(num_cpus=self.audit_cpus, scheduling_strategy=here).remote(
                self._series, self.series_kwargs)
        return self._actor


@contextlib.contextmanager
def _global_rng_kept():
    """Puts back the global random states (``random``, NumPy's, torch's, torch's thread count) afterwards."""
    import random
    import sys

    import numpy as np

    torch = sys.modules.get("torch")  # never imported here just for this
    saved = (random.getstate(), np.random.get_state(),
             (torch.get_rng_state(), torch.get_num_threads()) if torch is not None else None)
    try:
        yield
    finally:
        random.setstate(saved[0])
        np.random.set_state(saved[1])
        if saved[2] is not None:
            torch.set_rng_state(saved[2][0])
            torch.set_num_threads(saved[2][1])
