"""Per-iteration metrics and the paper's summary figures."""

from __future__ import annotations

from typing import Iterable, Mapping


def evals_to_reach(history: Iterable[Mapping[str, float]], qd_score: float) -> int | None:
    """Evaluations a run needed to first reach ``qd_score`` (the paper's Table 2), or None."""
    for record in history:
        if record["qd_score"] >= qd_score:
            return int(record["evals"])
    return None
