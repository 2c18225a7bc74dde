"""Per-iteration metrics and the paper's summary figures."""

from __future__ import annotations

from typing import Iterable, Mapping

import numpy as np


def evals_to_reach(history: Iterable[Mapping[str, float]], qd_score: float) -> int | None:
    """Evaluations a run needed to first reach ``qd_score`` (the paper's Table 2), or None."""
    for record in history:
        if record["qd_score"] >= qd_score:
            return int(record["evals"])
    return None


def mean_absolute_errors(
    *,
    predicted_objective: np.ndarray,
    predicted_measures: np.ndarray,
    predicted_occupancy: np.ndarray | None,
    objective: np.ndarray,
    measures: np.ndarray,
    occupancy: np.ndarray,
    measure_names: tuple[str, ...],
) -> dict[str, float]:
    """Surrogate error on a batch that was just evaluated for real, one entry per head."""
    errors = {"mae_objective": float(np.mean(np.abs(predicted_objective - objective)))}
    for j, name in enumerate(measure_names):
        errors[f"mae_{name}"] = float(np.mean(np.abs(predicted_measures[:, j] - measures[:, j])))
    if predicted_occupancy is not None:
        errors["mae_occupancy"] = float(np.mean(np.abs(predicted_occupancy - occupancy)))
    return errors
