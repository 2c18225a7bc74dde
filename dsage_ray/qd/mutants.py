"""Mutants of the ground-truth archive's best elites: real-evaluation picks beside DSAGE's downsampling.

The surrogate proposes levels spread over the measure space, but it cannot tell which level of a cell the agent
fails (within a cell it ranks the failure rate hardly better than chance). A real elite that the agent never
solves is better evidence: a MAP-Elites mutant of one is often never solved too. ``selection.elite_mutants``
spends part of each outer iteration on such mutants (not in the paper).
"""

from __future__ import annotations

import math
from typing import Callable

import numpy as np
from ribs.archives import ArchiveBase
from ribs.emitters.operators import GaussianOperator

from dsage_ray.config import MutatingEmitter, QDConfig
from dsage_ray.qd.emitters import mutate_bitmaps


def best_elites(archive: ArchiveBase, *, share: float) -> np.ndarray:
    """Positions (in ``archive.data()`` order) of the elites among the best ``share`` by objective.

    At least one elite is taken, and every elite tied with the worst one taken: an audit's never-solved
    levels all share the best objective, 1, so every one of them is among the parents however many there are.

    Args:
        archive: A non-empty archive.
        share: The fraction of its elites to take, in (0, 1].
    """
    objective = np.asarray(archive.data("objective"), dtype=np.float64)
    count = max(1, math.ceil(share * len(objective)))
    threshold = np.sort(objective)[::-1][count - 1]
    return np.flatnonzero(objective >= threshold)


def elite_mutants(archive: ArchiveBase, *, count: int, share: float, qd: QDConfig,
                  rng: np.random.Generator, bounds: tuple[float, float] | None = None,
                  evaluated: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
    """``count`` mutants of parents drawn uniformly (with replacement) among :func:`best_elites`, or among every
    evaluated level at least as good as the worst of them (``evaluated``).

    The mutation is the one of the configured direct search: ``qd.mutation_cells`` cells redrawn for
    ``map_elites`` (0/1 bitmaps), Gaussian noise of ``qd.sigma0`` for ``cma_me``, ``gaussian``, ``halton`` and
    ``cross_entropy`` (continuous vectors).

    Args:
        archive: The ground-truth archive; nothing is drawn when it is empty.
        count: Mutants to return.
        share: See :func:`best_elites`.
        qd: The run's QD config (its emitter names the mutation).
        rng: Draws the parents and the mutations.
        bounds: The domain's ``solution_bounds``: the mutants are clipped to them (``None``: not clipped).
        evaluated: ``(solutions, objective)`` of every level evaluated so far: the parents are those at least as
            good as the best elites (every fault played, on a fault objective), so a region dense with good levels
            parents more mutants than a lone one (``experimental.mutant_parents = "evaluated"``). ``None``: the
            best elites, one level a cell.

    Returns:
        ``(count, solution_dim)`` solutions in the archive's solution dtype, or none when the archive is empty.

    Raises:
        ValueError: ``qd.emitter`` has no mutation (``random`` draws fresh levels).
    """
    dtype = archive.dtypes["solution"]
    if count == 0 or archive.empty:
        return np.empty((0, archive.solution_dim), dtype=dtype)
    if evaluated is not None:
        elite_objective = np.asarray(archive.data("objective"))
        threshold = elite_objective[best_elites(archive, share=share)].min()
        solutions, objective = evaluated
        # Compared in the archive's precision: an elite's own evaluation is as good as the elite.
        parents = np.flatnonzero(np.asarray(objective, dtype=elite_objective.dtype) >= threshold)
        if parents.size:  # none only where the archive holds levels the record does not
            return mutate(np.asarray(solutions, dtype=dtype)[rng.choice(parents, size=count)], qd=qd, rng=rng,
                          bounds=bounds)
    solutions = np.asarray(archive.data("solution"), dtype=dtype)
    return mutate(solutions[rng.choice(best_elites(archive, share=share), size=count)], qd=qd, rng=rng,
                  bounds=bounds)


def _gaussian(parents: np.ndarray, qd: QDConfig, rng: np.random.Generator) -> np.ndarray:
    # pyribs' operator draws from its own generator; seeding it from ours keeps the run reproducible.
    return GaussianOperator(sigma=qd.sigma0, seed=int(rng.integers(2**63))).ask(parents)


def _bitmap(parents: np.ndarray, qd: QDConfig, rng: np.random.Generator) -> np.ndarray:
    return mutate_bitmaps(parents, cells=qd.mutation_cells, rng=rng)


#: The mutation of each ``qd.emitter`` that has one: ``mutation(parents, qd, rng)``. Its keys are the config's
#: :data:`~dsage_ray.config.MutatingEmitter` (``random`` draws fresh levels and has none).
MUTATIONS: dict[MutatingEmitter, Callable[[np.ndarray, QDConfig, np.random.Generator], np.ndarray]] = {
    "map_elites": _bitmap,
    "cma_me": _gaussian,
    "gaussian": _gaussian,
    "halton": _gaussian,
    "cross_entropy": _gaussian,
}


def mutate(parents: np.ndarray, *, qd: QDConfig, rng: np.random.Generator,
           bounds: tuple[float, float] | None = None) -> np.ndarray:
    """One mutant of each parent, with the operator of ``qd.emitter`` (see :func:`elite_mutants`).

    Args:
        bounds: ``(low, high)``: the mutants are clipped to them in every dimension (``None``: not clipped).

    Raises:
        ValueError: ``qd.emitter`` has no mutation (``random`` draws fresh levels).
    """
    if qd.emitter not in MUTATIONS:
        raise ValueError(f"qd.emitter {qd.emitter!r} has no mutation to make elite mutants with")
    mutants = MUTATIONS[qd.emitter](parents, qd, rng)
    return mutants if bounds is None else np.clip(mutants, *bounds).astype(mutants.dtype, copy=False)
