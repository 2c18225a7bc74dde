"""A cheap first look before the real evaluation: screen many surrogate elites, evaluate those that look new.

The surrogate places a pick by its prediction, and on the Maze with ACCEL that prediction misses the path length by
about 120 steps (30 archive cells): a quarter to a half of the picks land in cells the search already holds. A
domain that can evaluate a level with a few episodes instead of the configured count (``Domain.screen``, Maze:
:meth:`~dsage_ray.domains.maze.domain.MazeDomain.screen`) estimates where a level lands for a few percent of an
evaluation's cost. :func:`screen_picks` screens a pool of candidates (the selection's picks first, then other
elites predicted to add to the ground truth) and keeps, up to the selection's size, those whose screened
result would add to it (``selection.screen_episodes``; not in the paper).

A one-episode screen errs in a way its own history shows: a level ACCEL fails once may be one it usually solves,
and one it solves in 40 steps lands within a few cells of 40. With ``selection.screen_gain`` the candidates are
ranked by the QD-score they are expected to add, their screened result plus the errors the screen made on the
recently evaluated levels nearest to it (:func:`~dsage_ray.qd.gain.expected_outcomes`, a :class:`PickErrors` of
screened against real results). A candidate whose screened cell is empty but surrounded by filled ones then
ranks below one in an empty region.

The screened results are estimates: nothing here adds them to an archive or a dataset.
"""

from __future__ import annotations

import dataclasses
from typing import Callable

import numpy as np
from ribs.archives import GridArchive

from dsage_ray.qd.gain import EvaluationCost, PickErrors, expected_outcomes
from dsage_ray.qd.selection import adds_to, check_same_cells, gather_elites
from dsage_ray.types import Solutions

#: Screens solutions: their estimated ``(objective (n,), measures (n, m))``.
Screen = Callable[[Solutions], tuple[np.ndarray, np.ndarray]]


@dataclasses.dataclass(frozen=True)
class Screened:
    """What :func:`keep_screened` kept of the solutions it screened.

    Attributes:
        kept: Positions (ascending) of the solutions to evaluate.
        new: Solutions whose screened result would add to the ground truth (before one per cell is kept).
        estimates: ``(n, 1 + M)`` every solution's screened objective, then its measures.
        expected_new: With screen errors, the QD-score the kept ones are expected to add; NaN without.
    """

    kept: np.ndarray
    new: int
    estimates: np.ndarray
    expected_new: float = float("nan")


@dataclasses.dataclass(frozen=True)
class ScreenedPicks:
    """What :func:`screen_picks` kept.

    Attributes:
        kept: Sorted surrogate-archive indices to evaluate.
        screened: Candidates screened.
        new: Screened candidates whose estimate would add to the ground truth (before one per cell is kept).
        fallback: No candidate was kept, so the picks were kept as they were.
        estimates: ``(len(kept), 1 + M)`` the kept ones' screened objective and measures, in ``kept``'s order.
        expected_new: With screen errors, the QD-score the kept ones are expected to add; NaN without.
    """

    kept: np.ndarray
    screened: int
    new: int
    fallback: bool
    estimates: np.ndarray
    expected_new: float = float("nan")


def screen_picks(surrogate_archive: GridArchive, picks: np.ndarray, ground_truth_archive: GridArchive, *,
                 screen: Screen, pool: float, rng: np.random.Generator, errors: PickErrors | None = None,
                 neighbours: int = 64, cost: EvaluationCost | None = None) -> ScreenedPicks:
    """Screens the picks and more candidates, and keeps up to ``len(picks)`` whose estimates would add to the
    ground truth, at most one per estimated cell.

    Candidates are the picks, then, drawn at random, other elites of ``surrogate_archive`` predicted to add to
    the ground truth (an empty cell, or a higher objective than its elite), ``pool × len(picks)`` in all. A
    candidate is kept when the ground-truth cell at its *screened* measures is empty or holds a lower objective
    than its screened one, and no candidate kept before it has the same screened cell; the picks come first.

    With ``errors``, candidates are kept by their expected gain instead (:func:`keep_screened`).

    When no candidate qualifies, the picks are kept: the search then has nothing it believes is new, and
    spending nothing would stall it.

    Args:
        surrogate_archive: The archive the picks index (predicted objectives and measures).
        picks: Its indices chosen by the selection.
        ground_truth_archive: Real evaluations, over the same cells.
        screen: Estimates the candidates' objectives and measures.
        pool: Candidates screened per pick (at least 1).
        rng: Draws the extra candidates.
        errors: The screen's recent errors (screened against real results); None: the screened cell decides.
        neighbours: With ``errors``, how many of them, nearest in screened measures, lend a candidate theirs.
        cost: With ``errors``, what an evaluation costs: candidates are then ranked by expected gain per cost.

    Raises:
        ValueError: ``pool`` below 1, or the archives do not share their cells.
    """
    if pool < 1:
        raise ValueError(f"pool must be at least 1 (candidates screened per pick), got {pool}")
    check_same_cells(surrogate_archive, ground_truth_archive, "screen_picks")
    picks = np.sort(np.asarray(picks, dtype=np.int64))
    if len(picks) == 0:
        return ScreenedPicks(kept=picks, screened=0, new=0, fallback=False,
                             estimates=np.empty((0, 1 + ground_truth_archive.measure_dim)))
    others = np.setdiff1d(np.asarray(surrogate_archive.data("index"), dtype=np.int64), picks)
    if len(others):
        predicted = gather_elites(surrogate_archive, others)
        others = others[adds_to(ground_truth_archive, predicted["objective"], predicted["measures"])]
    extra = min(len(others), int(round(pool * len(picks))) - len(picks))
    candidates = np.concatenate([picks, rng.choice(others, size=max(extra, 0), replace=False)])
    screened = keep_screened(gather_elites(surrogate_archive, candidates)["solution"], ground_truth_archive,
                             screen=screen, limit=len(picks), errors=errors, neighbours=neighbours, cost=cost)
    # The picks are the first candidates: fallen back on, they keep their own estimates.
    kept = screened.kept if len(screened.kept) else np.arange(len(picks))
    order = np.argsort(candidates[kept], kind="stable")
    return ScreenedPicks(kept=candidates[kept][order], screened=len(candidates), new=screened.new,
                         fallback=not len(screened.kept), estimates=screened.estimates[kept][order],
                         expected_new=screened.expected_new)


def keep_screened(solutions: Solutions, ground_truth_archive: GridArchive, *, screen: Screen, limit: int,
                  errors: PickErrors | None = None, neighbours: int = 64,
                  cost: EvaluationCost | None = None) -> Screened:
    """Screens ``solutions`` and keeps at most ``limit`` of them that would add to the ground truth, one per
    screened cell.

    Without ``errors``, those whose screened result would add (an empty cell, or a higher objective than its
    elite) are kept in the order given, the first in each screened cell. With ``errors``, those expected to add
    most are kept, best first: each candidate's screened result plus the errors of the ``neighbours`` recent
    levels nearest in screened measures, landed in the ground-truth archive
    (:func:`~dsage_ray.qd.gain.expected_outcomes`); a candidate expected to add nothing is not kept. With a
    ``cost``, best means most expected gain per expected cost: the levels a search most wants are often those its
    agent fails, the dearest to evaluate. With an empty ``errors`` and no cost the estimates are taken at their
    word, which keeps what the first rule keeps.
    """
    objective, measures = screen(solutions)
    objective = np.asarray(objective, np.float64).reshape(-1)
    measures = np.asarray(measures, np.float64).reshape(len(objective), -1)
    estimates = np.column_stack([objective, measures])
    adding = adds_to(ground_truth_archive, objective, measures) if len(objective) else np.zeros(0, bool)
    if errors is None:
        order = np.flatnonzero(adding)
        gain = None
    else:
        outcomes = expected_outcomes(objective, measures, ground_truth_archive=ground_truth_archive, errors=errors,
                                     neighbours=neighbours, cost=cost)
        gain = outcomes.gain
        order = np.argsort(-outcomes.gain_per_cost, kind="stable")
        order = order[gain[order] > 0]
    cells = ground_truth_archive.index_of(measures[order]) if len(order) else np.empty(0, np.int64)
    first = order[np.sort(np.unique(cells, return_index=True)[1])][:limit]
    return Screened(kept=np.sort(first), new=int(adding.sum()), estimates=estimates,
                    expected_new=float("nan") if gain is None else float(gain[first].sum()))
