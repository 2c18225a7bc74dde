"""The figures the result tables print: mean ± standard error over runs, and the paper's Table 2 metric.

Shared by the benchmarks and the experiment scripts (``experiments/summarize.py``, ``experiments/audit_comparison.py``
put this folder on ``sys.path``); research code, not part of the dsage_ray package.
"""

from __future__ import annotations

import math
from typing import Iterable, Mapping


def evals_to_reach(history: Iterable[Mapping[str, float]], qd_score: float) -> int | None:
    """Evaluations a run needed to first reach ``qd_score`` (the paper's Table 2), or None."""
    for record in history:
        if record["qd_score"] >= qd_score:
            return int(record["evals"])
    return None


def mean_se(values: Iterable[float]) -> tuple[float, float]:
    """Mean and standard error over runs; the error is NaN for a single run (it is not zero, just unknown)."""
    values = [float(v) for v in values]
    mean = math.fsum(values) / len(values)
    if len(values) < 2:
        return mean, math.nan
    variance = math.fsum((v - mean) ** 2 for v in values) / (len(values) - 1)
    return mean, math.sqrt(variance / len(values))


def format_mean_se(mean: float, se: float, spec: str) -> str:
    """``"1,597.0 ± 17.5"`` (``spec`` formats both), or the mean alone when the error is unknown."""
    return format(mean, spec) if math.isnan(se) else f"{format(mean, spec)} ± {format(se, spec)}"
