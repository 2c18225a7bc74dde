"""Emitters pyribs does not ship: MAP-Elites on 0/1 bitmaps, and domain-random solutions."""

from __future__ import annotations

from typing import Callable

import numpy as np
from ribs.archives import ArchiveBase
from ribs.emitters import EmitterBase

#: Draws ``n`` solutions with the given generator, shape ``(n, solution_dim)``.
Sampler = Callable[[int, np.random.Generator], np.ndarray]


def _check_positive(**values: int) -> None:
    for name, value in values.items():
        if value < 1:
            raise ValueError(f"{name} must be positive (got {value})")


def _dtype_bounds(archive: ArchiveBase) -> tuple[np.ndarray, np.ndarray]:
    """The widest bounds the archive's solution dtype can hold.

    EmitterBase's default bounds are ±inf, which an integer dtype (an int8 Maze archive) cannot
    represent: numpy casts them to 0 with only a warning, and the emitter would claim bounds [0, 0].
    """
    dtype = archive.dtypes["solution"]
    info = np.iinfo(dtype) if np.issubdtype(dtype, np.integer) else None
    low, high = (info.min, info.max) if info is not None else (-np.inf, np.inf)
    return (np.full(archive.solution_dim, low, dtype=dtype), np.full(archive.solution_dim, high, dtype=dtype))


def mutate_bitmaps(parents: np.ndarray, *, cells: int, rng: np.random.Generator) -> np.ndarray:
    """MAP-Elites' bitmap mutation: each row with ``cells`` distinct random cells set to random 0/1 values.

    Args:
        parents: ``(n, solution_dim)`` 0/1 bitmaps; not modified.
        cells: Distinct cells redrawn per row (a cell can be redrawn to its old value).
        rng: Picks the cells and their values.

    Returns:
        The offspring, in the parents' dtype.
    """
    offspring = np.array(parents, copy=True)
    # argpartition of uniform keys = a uniformly random k-subset per row, without a Python loop.
    chosen = np.argpartition(rng.random(offspring.shape), cells - 1, axis=1)[:, :cells]
    np.put_along_axis(offspring, chosen, rng.integers(0, 2, size=chosen.shape).astype(offspring.dtype), axis=1)
    return offspring


class MapElitesBitmapEmitter(EmitterBase):
    """MAP-Elites for binary bitmaps, as DSAGE's Maze baseline and inner loop (SPEC §5).

    The first ``initial_random_batches`` calls to :meth:`ask` (and any call while the archive is
    empty) return uniformly random 0/1 bitmaps. Every later offspring is a uniformly sampled elite
    with ``mutation_cells`` distinct random cells set to random 0/1 values, so at most
    ``mutation_cells`` cells differ from the parent (a cell can be redrawn to its old value).

    Args:
        archive: Archive the parents come from; its RNG picks them (``sample_elites``).
        solution_dim: Cells per bitmap; must equal ``archive.solution_dim``.
        batch_size: Solutions per :meth:`ask`.
        mutation_cells: Distinct cells redrawn per offspring.
        initial_random_batches: Asks that return random bitmaps before mutation starts.
        seed: Seed of this emitter's RNG (random bitmaps, mutated cells and their values).

    Raises:
        ValueError: ``solution_dim`` does not match the archive, or a count is out of range.
    """

    def __init__(
        self,
        archive: ArchiveBase,
        *,
        solution_dim: int,
        batch_size: int,
        mutation_cells: int = 10,
        initial_random_batches: int = 4,
        seed: int | None = None,
    ) -> None:
        if solution_dim != archive.solution_dim:
            raise ValueError(f"solution_dim {solution_dim} does not match archive.solution_dim {archive.solution_dim}")
        _check_positive(batch_size=batch_size, mutation_cells=mutation_cells)
        if mutation_cells > solution_dim:
            raise ValueError(f"mutation_cells {mutation_cells} exceeds solution_dim {solution_dim}")
        if initial_random_batches < 0:
            raise ValueError(f"initial_random_batches must be >= 0 (got {initial_random_batches})")
        EmitterBase.__init__(
            self,
            archive,
            solution_dim=solution_dim,
            bounds=None,
            lower_bounds=np.zeros(solution_dim),
            upper_bounds=np.ones(solution_dim),
        )
        self._batch_size = batch_size
        self._mutation_cells = mutation_cells
        self._initial_random_batches = initial_random_batches
        self._rng = np.random.default_rng(seed)
        self._asks = 0

    @property
    def batch_size(self) -> int:
        """Solutions per :meth:`ask`."""
        return self._batch_size

    @property
    def mutation_cells(self) -> int:
        """Distinct cells redrawn per offspring."""
        return self._mutation_cells

    @property
    def asks(self) -> int:
        """Calls to :meth:`ask` so far."""
        return self._asks

    def ask(self) -> np.ndarray:
        """Returns a ``(batch_size, solution_dim)`` batch of 0/1 bitmaps in the archive's dtype."""
        dtype = self.archive.dtypes["solution"]
        shape = (self._batch_size, self.solution_dim)
        initial = self._asks < self._initial_random_batches
        self._asks += 1
        if initial or self.archive.empty:
            return self._rng.integers(0, 2, size=shape).astype(dtype)
        parents = np.asarray(self.archive.sample_elites(self._batch_size)["solution"], dtype=dtype)
        return mutate_bitmaps(parents, cells=self._mutation_cells, rng=self._rng)


class RandomEmitter(EmitterBase):
    """Asks fresh random solutions from the domain every time (DR, or random solutions through a scheduler).

    Args:
        archive: Archive the scheduler inserts into; only its solution shape and dtype are used.
        sampler: ``sampler(n, rng)`` returns ``(n, solution_dim)`` random solutions, e.g.
            ``domain.random_solutions``. Must be picklable for :mod:`~dsage_ray.core.checkpoint`
            (a bound method or module-level function, not a lambda).
        batch_size: Solutions per :meth:`ask`.
        seed: Seed of the generator passed to ``sampler``.
    """

    def __init__(
        self,
        archive: ArchiveBase,
        *,
        sampler: Sampler,
        batch_size: int,
        seed: int | None = None,
    ) -> None:
        _check_positive(batch_size=batch_size)
        lower, upper = _dtype_bounds(archive)
        EmitterBase.__init__(
            self,
            archive,
            solution_dim=archive.solution_dim,
            bounds=None,
            lower_bounds=lower,
            upper_bounds=upper,
        )
        self._sampler = sampler
        self._batch_size = batch_size
        self._rng = np.random.default_rng(seed)

    @property
    def batch_size(self) -> int:
        """Solutions per :meth:`ask`."""
        return self._batch_size

    def ask(self) -> np.ndarray:
        """Returns ``sampler(batch_size, rng)`` in the archive's solution dtype.

        Raises:
            ValueError: The sampler returned the wrong shape.
        """
        solutions = np.asarray(self._sampler(self._batch_size, self._rng), dtype=self.archive.dtypes["solution"])
        expected = (self._batch_size, self.solution_dim)
        if solutions.shape != expected:
            raise ValueError(f"sampler returned shape {solutions.shape}, expected {expected}")
        return solutions
