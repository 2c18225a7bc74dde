"""Audits during training: callbacks that audit an agent's checkpoints as they are written.

* :class:`dsage_ray.integrations.rllib.AuditCallback` — an RLlib callback (new API stack): every
  ``audit_every`` training iterations it saves the current RLModule and audits it with an
  :class:`~dsage_ray.audit.series.AuditSeries` (the regression suite re-evaluated, then a short
  warm-started DSAGE search whose new failures join the suite). The audit's scalars go into the
  iteration's result under ``"audit"`` and, optionally, to a TensorBoard writer under ``audit/…`` with
  step = environment steps.
* :class:`dsage_ray.integrations.tune.AuditCheckpointsCallback` — a ``ray.tune.Callback`` that audits every
  ``audit_every``-th checkpoint any Tune trainable writes.

An audit that fails, for any reason, logs one warning line (``audit of iter_N skipped: <reason>``) and
never stops training. Names load lazily: importing this package imports neither Ray nor torch.
"""

from __future__ import annotations

import contextlib
import logging
import math
import os
from pathlib import Path
from typing import Any, Callable, Mapping

__all__ = ["AuditCallback", "AuditCheckpointsCallback", "SeriesAuditor", "DEFAULT_AUDIT_EVERY", "DEFAULT_AUDIT_BUDGET",
           "DEFAULT_PRESET", "DEFAULT_EPISODES", "DEFAULT_OVERRIDES"]

#: Training iterations (RLlib) or checkpoints (Tune) between audits, by default.
DEFAULT_AUDIT_EVERY = 25
#: Real evaluations of each audit's DSAGE search, by default.
DEFAULT_AUDIT_BUDGET = 30
#: The audit's preset (its search settings; ``budget`` replaces the preset's).
DEFAULT_PRESET = "tiny"
#: Episodes per level when the suite and the new failures are re-evaluated (None: the preset's, 5 for ``tiny``).
DEFAULT_EPISODES = None
#: The series folder inside a callback's ``out_dir`` (module checkpoints go to ``out_dir/checkpoints``).
SERIES_SUBDIR = "audit_series"
#: Config keys of every audit unless the caller's ``overrides`` set them: a smaller random start and
#: selection than ``tiny`` (so that ``audit_budget`` 30 is one cold outer iteration after 20 random levels, or
#: three warm-started ones), and no elite pictures in the search's TensorBoard.
DEFAULT_OVERRIDES: Mapping[str, Any] = {"n_rand": 20, "selection.count": 10, "image_levels": 0}

log = logging.getLogger(__name__)

_WHERE = {"AuditCallback": "dsage_ray.integrations.rllib", "AuditCheckpointsCallback": "dsage_ray.integrations.tune"}


def __getattr__(name: str) -> Any:
    if name in _WHERE:
        import importlib

        return getattr(importlib.import_module(_WHERE[name]), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def describe(exc: BaseException, *, limit: int = 200) -> str:
    """``"Type: first line of the message"``, shortened to one log line."""
    lines = str(exc).strip().splitlines()
    line = lines[0] if lines else ""
    line = line if len(line) <= limit else line[: limit - 3] + "..."
    return f"{type(exc).__name__}: {line}" if line else type(exc).__name__


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


class SeriesAuditor:
    """What the callbacks share: an audit series built on first use, a TensorBoard writer, and the fault rule.

    Args:
        out_dir: The series folder (``series.json``, one folder per audit); an existing series there is
            continued.
        series: None (an :class:`~dsage_ray.audit.series.AuditSeries` on ``out_dir`` with the settings
            below), an object with ``audit(spec, label=, step=)``, or a factory called with the
            ``AuditSeries`` keyword arguments that returns one.
        writer: Where the audit's scalars also go: an object with ``add_scalar(tag, value, step)`` (a
            ``SummaryWriter``), a folder to open a ``tensorboardX.SummaryWriter`` on when the first audit
            ends, or None.
        audit_budget: Real evaluations of each audit's search.
        preset, domain, seed, overrides, local, workers, address, episodes, warm_start: The
            ``AuditSeries`` settings (``local``: audits run in this process, no Ray actors).
            ``overrides`` go over :data:`DEFAULT_OVERRIDES`.

    The global random states (``random``, NumPy's, torch's) are put back after every audit, so that an
    audit does not change what the training samples next: a training with audits is the training without.
    """

    def __init__(
        self,
        *,
        out_dir: str | os.PathLike[str],
        series: Any = None,
        writer: Any = None,
        audit_budget: int = DEFAULT_AUDIT_BUDGET,
        preset: str | None = DEFAULT_PRESET,
        domain: str = "maze",
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
        self.out_dir = Path(out_dir)
        self.series_kwargs = dict(out_dir=self.out_dir, domain=domain, preset=preset, budget=int(audit_budget),
                                  seed=seed, overrides={**DEFAULT_OVERRIDES, **dict(overrides or {})}, local=local, workers=workers,
                                  address=address, episodes=episodes, warm_start=warm_start)
        self._series = series
        self._series_built = series is not None and hasattr(series, "audit")
        self._writer = writer

    @property
    def series(self) -> Any:
        """The series the audits go to (built on first use, so that constructing a callback is cheap)."""
        if not self._series_built:
            if self._series is None:
                from dsage_ray.audit.series import AuditSeries

                self._series = AuditSeries(**self.series_kwargs)
            else:
                self._series = self._series(**self.series_kwargs)
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

    def audit(self, spec: str | Callable[[], str], *, label: str, step: int | None) -> Any:
        """Audits one checkpoint; the series' record, or None when the audit raised (one warning logged).

        ``spec`` may be a callable that produces the agent spec (e.g. by saving the checkpoint): what
        it raises counts as a failed audit too. A record whose ``error`` is set logs the same one
        warning; its scalars that are numbers still go to the writer.
        """
        try:
            if callable(spec):
                spec = spec()
            with _one_warning(), _global_rng_kept():
                record = self.series.audit(spec, label=label, step=step)
        except Exception as exc:  # noqa: BLE001 - an audit must never stop training
            log.warning("audit of %s skipped: %s", label, describe(exc))
            return None
        if getattr(record, "error", None):
            reason = str(record.error).strip().splitlines()
            log.warning("audit of %s skipped: %s", label, reason[-1] if reason else "unknown error")
        try:
            self.write(finite_scalars(record), step)
        except Exception as exc:  # noqa: BLE001
            log.warning("audit of %s: scalars not written: %s", label, describe(exc))
        return record

    def write(self, scalars: Mapping[str, float], step: int | None) -> None:
        """Writes ``scalars`` (``audit/...`` tags) to the writer, if there is one, at ``step``."""
        writer = self.writer
        if writer is None or not scalars:
            return
        for tag, value in scalars.items():
            writer.add_scalar(tag, value, step)
        if hasattr(writer, "flush"):
            writer.flush()


class _SeriesFailureFilter(logging.Filter):
    """Drops the series' own warning about a failed checkpoint: the auditor's line says it instead."""

    def filter(self, record: logging.LogRecord) -> bool:
        return not (record.levelno == logging.WARNING and str(record.msg).startswith("audit-series: checkpoint"))


@contextlib.contextmanager
def _one_warning():
    """While an audit runs, its failure is logged once (``audit of ... skipped``), not also by the series."""
    series_log, drop = logging.getLogger("dsage_ray.audit.series"), _SeriesFailureFilter()
    series_log.addFilter(drop)
    try:
        yield
    finally:
        series_log.removeFilter(drop)


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
