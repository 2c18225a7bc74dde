"""Audits during training: callbacks that audit an agent's checkpoints as they are written.

* :class:`dsage_ray.integrations.rllib.AuditCallback` — an RLlib callback (new API stack): every
  ``audit_every`` training iterations it saves the current RLModule and audits it with an
  :class:`~dsage_ray.audit.series.AuditSeries` (the regression suite re-evaluated, then a short
  warm-started DSAGE search whose new failures join the suite). The audit's scalars go into the
  iteration's result under ``"audit"`` and, optionally, to a TensorBoard writer under ``audit/…`` with
  step = environment steps.
* :class:`dsage_ray.integrations.tune.AuditCheckpointsCallback` — a ``ray.tune.Callback`` that audits every
  ``audit_every``-th checkpoint any Tune trainable writes.

By default the audits run in the background, in a Ray actor with a CPU of its own
(:class:`~dsage_ray.integrations.auditor.SeriesAuditor`): training waits only for the checkpoint to be written.
An audit that fails, for any reason, logs one warning line (``audit of iter_N skipped: <reason>``) and never
stops training. Names load lazily: importing this package imports neither Ray nor torch.

Modules: :mod:`.defaults` (the default settings), :mod:`.auditor` (what the callbacks share),
:mod:`.series_actor` (the series and its Ray actor), :mod:`.faults` (the fault rule's log lines), :mod:`.rllib`,
:mod:`.tune`, and :mod:`.training` (what the training scripts share). This package only re-exports.
"""

from __future__ import annotations

from typing import Any

from dsage_ray.integrations.auditor import FinishedAudit, SeriesAuditor, finite_scalars
from dsage_ray.integrations.defaults import (DEFAULT_AUDIT_BUDGET, DEFAULT_AUDIT_EVERY, DEFAULT_EPISODES,
                                             DEFAULT_OVERRIDES, DEFAULT_PRESET, SERIES_SUBDIR)
from dsage_ray.integrations.faults import describe, log
from dsage_ray.integrations.series_actor import SeriesActor, build_series

__all__ = ["AuditCallback", "AuditCheckpointsCallback", "SeriesAuditor", "DEFAULT_AUDIT_EVERY", "DEFAULT_AUDIT_BUDGET",
           "DEFAULT_PRESET", "DEFAULT_EPISODES", "DEFAULT_OVERRIDES"]

# The callbacks import Ray: loaded on first use, so that importing this package imports neither Ray nor torch.
_WHERE = {"AuditCallback": "dsage_ray.integrations.rllib", "AuditCheckpointsCallback": "dsage_ray.integrations.tune"}


def __getattr__(name: str) -> Any:
    if name in _WHERE:
        import importlib

        return getattr(importlib.import_module(_WHERE[name]), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
