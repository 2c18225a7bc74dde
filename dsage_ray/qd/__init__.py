"""Quality diversity on pyribs 0.12: archives, emitters, schedulers and solution selection."""

from dsage_ray.qd.archives import (
    OCCUPANCY_FIELD,
    archive_stats,
    archive_to_dataframe,
    make_archive,
)
from dsage_ray.qd.emitters import CrossEntropyEmitter, HaltonEmitter, MapElitesBitmapEmitter, RandomEmitter
from dsage_ray.qd.gain import EvaluationCost, GainPicks, Outcomes, PickErrors, best_per_block, expected_outcomes
from dsage_ray.qd.optimizer import InnerLoopTimings, emitter_seeds, make_emitters, make_scheduler, run_inner_loop
from dsage_ray.qd.selection import (
    SELECTION_METHODS,
    FilledSkip,
    block_ids,
    gather_elites,
    select_solutions,
    skip_filled,
)

__all__ = [
    "OCCUPANCY_FIELD",
    "SELECTION_METHODS",
    "CrossEntropyEmitter",
    "EvaluationCost",
    "FilledSkip",
    "GainPicks",
    "HaltonEmitter",
    "InnerLoopTimings",
    "MapElitesBitmapEmitter",
    "Outcomes",
    "PickErrors",
    "RandomEmitter",
    "archive_stats",
    "archive_to_dataframe",
    "best_per_block",
    "block_ids",
    "emitter_seeds",
    "expected_outcomes",
    "gather_elites",
    "make_archive",
    "make_emitters",
    "make_scheduler",
    "run_inner_loop",
    "select_solutions",
    "skip_filled",
]
