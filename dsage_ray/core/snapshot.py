"""A read-only view of a run after an outer iteration: what outputs and callbacks may read."""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING, Any, Mapping

import numpy as np

from dsage_ray.config import RunConfig
from dsage_ray.types import Domain

if TYPE_CHECKING:
    from ribs.archives import GridArchive

    from dsage_ray.qd.growth import GrowthPoint


@dataclasses.dataclass(frozen=True, kw_only=True)
class RunSnapshot:
    """The state of a run that its outputs (run folder, TensorBoard, progress lines) are made from.

    Taken by :meth:`DSAGE.snapshot <dsage_ray.core.runner.DSAGE.snapshot>` after every outer iteration.
    The fields cannot be reassigned and the sequences are tuples; the archive is the run's own (copying
    it every iteration would cost more than the outputs), so a reader must not add to it.

    Attributes:
        config: The run's config.
        domain: The run's domain (for measure names and rendering).
        archive: The ground-truth archive.
        history: One metrics row per outer iteration so far.
        failures: Evaluations that failed, with their seed and error.
        evals: Real evaluations spent.
        outer_iteration: Outer iterations done.
        wall_time: Seconds spent stepping, over the run including resumes.
        done: The evaluation or the time budget is spent.
        last_predictions: ``(predicted, true)`` measures of the last batch a surrogate predicted, or None.
        growth: The archive's numbers within the last outer iteration, as its results arrived
            (:func:`~dsage_ray.qd.growth.growth_curve`; empty before the first).
    """

    config: RunConfig
    domain: Domain
    archive: "GridArchive"
    history: tuple[Mapping[str, float], ...]
    failures: tuple[Mapping[str, Any], ...]
    evals: int
    outer_iteration: int
    wall_time: float
    done: bool
    last_predictions: tuple[np.ndarray, np.ndarray] | None
    growth: tuple["GrowthPoint", ...] = ()
