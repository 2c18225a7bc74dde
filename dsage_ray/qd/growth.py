"""The ground-truth archive's numbers within an outer iteration, as the batch's results arrive one at a time.

An outer iteration evaluates its whole batch before the archive takes it, so the archive's own numbers
change once per iteration. :func:`growth_curve` reads what they would have been after each result, without
changing the archive, so a run's record (e.g. its TensorBoard curves) can show the search's shape within an
iteration too.
"""

from __future__ import annotations

import dataclasses
import math
from typing import TYPE_CHECKING, Sequence

import numpy as np

from dsage_ray.qd.archives import archive_stats

if TYPE_CHECKING:
    from ribs.archives import GridArchive

#: Points of the within-iteration curves over a whole run's budget (TensorBoard shows up to 1,000 per tag).
GROWTH_POINTS = 500


@dataclasses.dataclass(frozen=True)
class GrowthPoint:
    """The ground-truth archive's numbers after ``evals`` real evaluations, within an outer iteration."""

    evals: int
    qd_score: float
    coverage: float
    objective_max: float


def growth_curve(archive: "GridArchive", *, measures: np.ndarray, objective: np.ndarray, evals_at: Sequence[int],
                 budget: int) -> tuple[GrowthPoint, ...]:
    """What ``archive`` would read as a batch's results entered it one at a time, every
    ``ceil(budget / GROWTH_POINTS)`` evaluations.

    Call it before the batch is added: it reads the archive (its numbers, and the elites of the cells the
    batch falls in) and changes nothing, so the search is the same with or without it. A cell keeps its
    best objective, as the ground-truth archive does, so after the whole batch the numbers are the ones
    the archive then holds.

    Args:
        archive: The ground-truth archive, before the batch.
        measures, objective: The batch's successful results, in evaluation order.
        evals_at: The run's evaluation count once each of them was evaluated (failed ones are counted, not listed).
        budget: The run's evaluation budget, which spaces the points.

    Returns:
        A point at each evaluation count in ``evals_at`` that is a multiple of the spacing.
    """
    if len(objective) == 0:
        return ()
    every = max(1, math.ceil(budget / GROWTH_POINTS))
    stats = archive_stats(archive)
    qd_score, elites, best = stats["qd_score"], stats["num_elites"], stats["objective_max"]
    occupied, elites_data = archive.retrieve(measures)
    cells = archive.index_of(measures)
    # Only the cells the batch falls in can change: their current elites' objectives, then the batch's.
    cell_objective = {int(c): float(o) for c, o, held in zip(cells, elites_data["objective"], occupied) if held}
    points = []
    for cell, value, at in zip(cells.tolist(), np.asarray(objective, dtype=np.float64).tolist(), evals_at):
        old = cell_objective.get(cell)
        if old is None or value > old:
            qd_score += value - (old or 0.0)
            elites += int(old is None)
            cell_objective[cell] = value
        best = value if math.isnan(best) else max(best, value)
        if at % every == 0:
            points.append(GrowthPoint(evals=int(at), qd_score=qd_score, coverage=elites / archive.cells,
                                      objective_max=best))
    return tuple(points)
