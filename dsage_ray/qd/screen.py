"""A cheap first look before the real evaluation: screen many surrogate elites, evaluate those that look new.

The surrogate places a pick by its prediction, and on the Maze with ACCEL that prediction misses the path length by
about 120 steps (30 archive cells): a quarter to a half of the picks land in cells the search already holds. A
domain that can evaluate a level with a few episodes instead of the configured count (``Domain.screen``, Maze:
:meth:`~dsage_ray.domains.maze.domain.MazeDomain.screen`) estimates where a level lands for a few percent of an
evaluation's cost. :func:`screen_picks` screens a pool of candidates (the selection's picks first, then other
elites predicted to add to the ground truth) and keeps, up to the selection's size, those whose screened
result would add to it (``selection.screen_episodes``; not in the paper).

The screened results are estimates: nothing here adds them to an archive or a dataset.
"""

from __future__ import annotations

import dataclasses
from typing import Callable

import numpy as np
from ribs.archives import GridArchive

from dsage_ray.qd.selection import adds_to, check_same_cells, gather_elites
from dsage_ray.types import Solutions

#: Screens solutions: their estimated ``(objective (n,), measures (n, m))``.
Screen = Callable[[Solutions], tuple[np.ndarray, np.ndarray]]


@dataclasses.dataclass(frozen=True)
class ScreenedPicks:
    """What :func:`screen_picks` kept.

    Attributes:
        kept: Sorted surrogate-archive indices to evaluate.
        screened: Candidates screened.
        new: Screened candidates whose estimate would add to the ground truth (before one per cell is kept).
        fallback: No candidate's estimate would add anything, so the picks were kept as they were.
    """

    kept: np.ndarray
    screened: int
    new: int
    fallback: bool


def screen_picks(surrogate_archive: GridArchive, picks: np.ndarray, ground_truth_archive: GridArchive, *,
                 screen: Screen, pool: float, rng: np.random.Generator) -> ScreenedPicks:
    """Screens the picks and more candidates, and keeps up to ``len(picks)`` whose estimates would add to the
    ground truth, at most one per estimated cell.

    Candidates are the picks, then, drawn at random, other elites of ``surrogate_archive`` predicted to add to
    the ground truth (an empty cell, or a higher objective than its elite), ``pool × len(picks)`` in all. A
    candidate is kept when the ground-truth cell at its *screened* measures is empty or holds a lower objective
    than its screened one, and no candidate kept before it has the same screened cell; the picks come first.

    When no candidate qualifies, the picks are kept: the search then has nothing it believes is new, and
    spending nothing would stall it (as :func:`~dsage_ray.qd.selection.skip_filled` does).

    Args:
        surrogate_archive: The archive the picks index (predicted objectives and measures).
        picks: Its indices chosen by the selection.
        ground_truth_archive: Real evaluations, over the same cells.
        screen: Estimates the candidates' objectives and measures.
        pool: Candidates screened per pick (at least 1).
        rng: Draws the extra candidates.

    Raises:
        ValueError: ``pool`` below 1, or the archives do not share their cells.
    """
    if pool < 1:
        raise ValueError(f"pool must be at least 1 (candidates screened per pick), got {pool}")
    check_same_cells(surrogate_archive, ground_truth_archive, "screen_picks")
    picks = np.sort(np.asarray(picks, dtype=np.int64))
    if len(picks) == 0:
        return ScreenedPicks(kept=picks, screened=0, new=0, fallback=False)
    others = np.setdiff1d(np.asarray(surrogate_archive.data("index"), dtype=np.int64), picks)
    if len(others):
        predicted = gather_elites(surrogate_archive, others)
        others = others[adds_to(ground_truth_archive, predicted["objective"], predicted["measures"])]
    extra = min(len(others), int(round(pool * len(picks))) - len(picks))
    candidates = np.concatenate([picks, rng.choice(others, size=max(extra, 0), replace=False)])
    kept, new = keep_screened(gather_elites(surrogate_archive, candidates)["solution"], ground_truth_archive,
                              screen=screen, limit=len(picks))
    if len(kept) == 0:
        return ScreenedPicks(kept=picks, screened=len(candidates), new=0, fallback=True)
    return ScreenedPicks(kept=np.sort(candidates[kept]), screened=len(candidates), new=new, fallback=False)


def keep_screened(solutions: Solutions, ground_truth_archive: GridArchive, *, screen: Screen,
                  limit: int) -> tuple[np.ndarray, int]:
    """Screens ``solutions`` and returns the positions of at most ``limit`` whose screened result would add to the
    ground truth (an empty cell, or a higher objective than its elite), the first in each screened cell, in order;
    and how many would add in all."""
    objective, measures = screen(solutions)
    measures = np.asarray(measures, np.float64)
    adding = np.flatnonzero(adds_to(ground_truth_archive, objective, measures))
    cells = ground_truth_archive.index_of(measures[adding]) if len(adding) else np.empty(0, np.int64)
    return np.sort(adding[np.unique(cells, return_index=True)[1]])[:limit], len(adding)
