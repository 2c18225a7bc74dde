"""Quality diversity on pyribs 0.12: archives, emitters, schedulers and solution selection."""

from dsage_ray.qd.archives import (
    OCCUPANCY_FIELD,
    archive_stats,
    archive_to_dataframe,
    make_archive,
)
from dsage_ray.qd.emitters import CrossEntropyEmitter, HaltonEmitter, MapElitesBitmapEmitter, RandomEmitter
from dsage_ray.qd.gain import EvaluationCost, Outcomes, PickErrors, expected_outcomes
from dsage_ray.qd.optimizer import InnerLoopTimings, emitter_seeds, make_emitters, make_scheduler, run_inner_loop
from dsage_ray.qd.selection import (
    SELECTION_METHODS,
    block_ids,
    gather_elites,
    select_solutions,
)

__all__ = [
    "OCCUPANCY_FIELD",
    "SELECTION_METHODS",
    "CrossEntropyEmitter",
    "EvaluationCost",
    "HaltonEmitter",
    "InnerLoopTimings",
    "MapElitesBitmapEmitter",
    "Outcomes",
    "PickErrors",
    "RandomEmitter",
    "archive_stats",
    "archive_to_dataframe",
    "block_ids",
    "emitter_seeds",
    "expected_outcomes",
    "gather_elites",
    "make_archive",
    "make_emitters",
    "make_scheduler",
    "run_inner_loop",
    "select_solutions",
]
