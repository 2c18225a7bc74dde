"""The audit series a :class:`~dsage_ray.integrations.auditor.SeriesAuditor` audits with, and the Ray actor that
holds it for background audits."""

from __future__ import annotations

from typing import Any, Mapping

from dsage_ray.integrations.faults import one_warning


def build_series(series: Any, kwargs: Mapping[str, Any]) -> Any:
    """The series object: an ``AuditSeries`` for None, else the factory's product."""
    if series is None:
        from dsage_ray.audit.series import AuditSeries

        return AuditSeries(**kwargs)
    return series(**kwargs)


class SeriesActor:
    """The series of background audits, in a Ray actor of its own (one torch thread)."""

    def __init__(self, series: Any, kwargs: Mapping[str, Any]) -> None:
        import torch

        torch.set_num_threads(1)
        self.series = build_series(series, kwargs)

    def audit(self, spec: str, label: str, step: int | None) -> Any:
        with one_warning():
            return self.series.audit(spec, label=label, step=step)
