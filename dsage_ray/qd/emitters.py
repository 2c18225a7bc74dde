"""Emitters pyribs does not ship: MAP-Elites on 0/1 bitmaps, domain-random solutions, and two searches of a
continuous box: Halton quasi-random samples and a cross-entropy falsifier."""

from __future__ import annotations

import math
from typing import Any, Callable

import numpy as np
from ribs.archives import ArchiveBase
from ribs.emitters import EmitterBase
from scipy.stats import qmc

#: Draws ``n`` solutions with the given generator, shape ``(n, solution_dim)``.
Sampler = Callable[[int, np.random.Generator], np.ndarray]


def _check_positive(**values: int) -> None:
    for name, value in values.items():
        if value < 1:
            raise ValueError(f"{name} must be positive (got {value})")


def check_box(bounds: tuple[float, float]) -> tuple[float, float]:
    """``bounds`` as ``(low, high)`` floats, checked finite with ``low < high``.

    Raises:
        ValueError: Not a pair, not finite, or ``low >= high``.
    """
    try:
        low, high = (float(b) for b in bounds)
    except (TypeError, ValueError):
        raise ValueError(f"bounds must be a pair (low, high) of numbers (got {bounds!r})") from None
    if not (math.isfinite(low) and math.isfinite(high) and low < high):
        raise ValueError(f"bounds must be finite with low < high (got {bounds!r})")
    return low, high


def _box_emitter_init(emitter: EmitterBase, archive: ArchiveBase, bounds: tuple[float, float]) -> tuple[float, float]:
    """EmitterBase's init with the same ``bounds`` in every dimension; returns the checked ``(low, high)``."""
    low, high = check_box(bounds)
    dim = archive.solution_dim
    EmitterBase.__init__(emitter, archive, solution_dim=dim, bounds=None, lower_bounds=np.full(dim, low),
                         upper_bounds=np.full(dim, high))
    return low, high


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
    """MAP-Elites for binary bitmaps, as DSAGE's Maze baseline and inner loop (SPEC: the QD searches).

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
            ``domain.random_solutions``. It is code, so a pickle (a checkpoint) leaves it out: whoever restores the
            emitter :meth:`attach`-es the sampler again.
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

    def attach(self, sampler: Sampler | None) -> None:
        """Sets the sampler (after a checkpoint restored the emitter without one)."""
        self._sampler = sampler

    def __getstate__(self) -> dict[str, Any]:
        return {**self.__dict__, "_sampler": None}

    def ask(self) -> np.ndarray:
        """Returns ``sampler(batch_size, rng)`` in the archive's solution dtype.

        Raises:
            ValueError: The sampler returned the wrong shape.
            RuntimeError: No sampler attached (a restored emitter nobody attached one to).
        """
        if self._sampler is None:
            raise RuntimeError("RandomEmitter restored from a checkpoint without its sampler: call attach() first")
        solutions = np.asarray(self._sampler(self._batch_size, self._rng), dtype=self.archive.dtypes["solution"])
        expected = (self._batch_size, self.solution_dim)
        if solutions.shape != expected:
            raise ValueError(f"sampler returned shape {solutions.shape}, expected {expected}")
        return solutions


class HaltonEmitter(EmitterBase):
    """Quasi-random solutions in a box: a scrambled Halton sequence (low discrepancy), one batch per ask.

    The emitter keeps its place in the sequence from one :meth:`ask` to the next (and through a pickle, as
    :mod:`~dsage_ray.core.checkpoint` saves it), so the batches together cover the box more evenly than
    independent uniform draws. It ignores the archive and what it is told.

    Args:
        archive: Archive the scheduler inserts into; only its solution shape and dtype are used.
        bounds: ``(low, high)``, the same in every dimension.
        batch_size: Solutions per :meth:`ask`.
        seed: Seed of the sequence's scrambling (``None``: unseeded).

    Raises:
        ValueError: ``bounds`` is not a finite pair with low < high, or ``batch_size`` < 1.
    """

    def __init__(
        self,
        archive: ArchiveBase,
        *,
        bounds: tuple[float, float] = (-1.0, 1.0),
        batch_size: int,
        seed: int | None = None,
    ) -> None:
        _check_positive(batch_size=batch_size)
        self._low, self._high = _box_emitter_init(self, archive, bounds)
        self._batch_size = batch_size
        self._engine = qmc.Halton(d=archive.solution_dim, scramble=True, rng=seed)

    @property
    def batch_size(self) -> int:
        """Solutions per :meth:`ask`."""
        return self._batch_size

    @property
    def num_generated(self) -> int:
        """Points of the sequence drawn so far (the next :meth:`ask` starts there)."""
        return int(self._engine.num_generated)

    def ask(self) -> np.ndarray:
        """Returns the sequence's next ``batch_size`` points, scaled to the box, in the archive's dtype."""
        unit = self._engine.random(self._batch_size)
        solutions = self._low + (self._high - self._low) * unit
        return np.clip(solutions, self._low, self._high).astype(self.archive.dtypes["solution"])


class CrossEntropyEmitter(EmitterBase):
    """A cross-entropy falsifier (as VerifAI's): a Gaussian over a box, refitted to the best of each batch.

    Each :meth:`ask` samples ``batch_size`` solutions from a Gaussian with a diagonal covariance, clipped to
    the box. Each :meth:`tell` fits a mean and per-dimension std to the ``elite_fraction`` of the told batch
    with the highest objective (the search maximises the objective: the highest is the worst for the agent),
    and moves the distribution towards the fit: ``new = smoothing * fit + (1 - smoothing) * old``, the std
    floored at ``min_std`` so the search never collapses to a point. The archive is not read: the emitter
    chases high objective, the archive keeps whatever it finds along the way.

    The covariance is diagonal: a full one fitted to a few elites (6 of a batch of 30) in many dimensions
    would be singular.

    Args:
        archive: Archive the scheduler inserts into; only its solution shape and dtype are used.
        bounds: ``(low, high)``, the same in every dimension.
        batch_size: Solutions per :meth:`ask`.
        elite_fraction: Share of a told batch the distribution is refitted to (at least one solution).
        smoothing: Weight of the new fit against the old distribution, in (0, 1].
        initial_std: Std of the first distribution (its mean is the box's centre); ``None``: half the box's
            width, so one std reaches each face.
        min_std: Floor of every std; ``None``: 2.5% of the box's width.
        seed: Seed of this emitter's sampling generator.

    Raises:
        ValueError: An argument out of its range.
    """

    def __init__(
        self,
        archive: ArchiveBase,
        *,
        bounds: tuple[float, float] = (-1.0, 1.0),
        batch_size: int,
        elite_fraction: float = 0.2,
        smoothing: float = 0.7,
        initial_std: float | None = None,
        min_std: float | None = None,
        seed: int | None = None,
    ) -> None:
        _check_positive(batch_size=batch_size)
        low, high = _box_emitter_init(self, archive, bounds)
        width = high - low
        initial_std = width / 2 if initial_std is None else float(initial_std)
        min_std = 0.025 * width if min_std is None else float(min_std)
        if not 0.0 < elite_fraction <= 1.0:
            raise ValueError(f"elite_fraction must be in (0, 1] (got {elite_fraction})")
        if not 0.0 < smoothing <= 1.0:
            raise ValueError(f"smoothing must be in (0, 1] (got {smoothing})")
        if not 0.0 < min_std <= initial_std:
            raise ValueError(f"need 0 < min_std <= initial_std (got min_std {min_std}, initial_std {initial_std})")
        self._batch_size = batch_size
        self._elite_fraction = float(elite_fraction)
        self._smoothing = float(smoothing)
        self._min_std = min_std
        self._mean = np.full(archive.solution_dim, (low + high) / 2)
        self._std = np.full(archive.solution_dim, initial_std)
        self._rng = np.random.default_rng(seed)
        self._tells = 0

    @property
    def batch_size(self) -> int:
        """Solutions per :meth:`ask`."""
        return self._batch_size

    @property
    def mean(self) -> np.ndarray:
        """The distribution's mean, ``(solution_dim,)`` (a copy)."""
        return self._mean.copy()

    @property
    def std(self) -> np.ndarray:
        """The distribution's per-dimension std, ``(solution_dim,)``, never below :attr:`min_std` (a copy)."""
        return self._std.copy()

    @property
    def min_std(self) -> float:
        """Floor of every std."""
        return self._min_std

    @property
    def tells(self) -> int:
        """Batches the distribution was refitted to so far."""
        return self._tells

    def ask(self) -> np.ndarray:
        """Returns ``batch_size`` draws of the distribution, clipped to the box, in the archive's dtype."""
        noise = self._rng.standard_normal((self._batch_size, self.solution_dim))
        solutions = np.clip(self._mean + self._std * noise, self.lower_bounds, self.upper_bounds)
        return solutions.astype(self.archive.dtypes["solution"])

    def tell(self, solution: Any, objective: Any, measures: Any, add_info: Any, **fields: Any) -> None:
        """Refits the distribution to the best ``elite_fraction`` of ``solution`` by ``objective``.

        Args:
            solution: ``(n, solution_dim)``: the batch this emitter asked, as evaluated.
            objective: ``(n,)``; higher is better for the search. NaN ranks last.
            measures: Unused.
            add_info: Unused (the archive's verdicts: the emitter chases objective, not new cells).
            fields: Unused.
        """
        solution = np.asarray(solution, dtype=np.float64)
        objective = np.asarray(objective, dtype=np.float64)
        if len(objective) == 0:
            return
        count = max(1, math.ceil(self._elite_fraction * len(objective)))
        # Descending by objective; argsort puts NaN last, and -NaN is NaN, so NaN ranks worst.
        elites = solution[np.argsort(-objective, kind="stable")[:count]]
        alpha = self._smoothing
        self._mean = alpha * elites.mean(axis=0) + (1 - alpha) * self._mean
        self._std = np.maximum(alpha * elites.std(axis=0) + (1 - alpha) * self._std, self._min_std)
        self._tells += 1
