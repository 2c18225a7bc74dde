"""Schedulers for the configured QD algorithm and the ask → predict → tell inner loop."""

from __future__ import annotations

import dataclasses
import time
from typing import Any, Callable, Mapping

import numpy as np
from ribs.archives import ArchiveBase
from ribs.emitters import EmitterBase, EvolutionStrategyEmitter, GaussianEmitter
from ribs.schedulers import Scheduler

from dsage_ray.config import ConfigError, EmitterName, QDConfig
from dsage_ray.errors import did_you_mean
from dsage_ray.qd.emitters import (CrossEntropyEmitter, HaltonEmitter, MapElitesBitmapEmitter, RandomEmitter, Sampler,
                                   check_box)

#: The box the continuous searches (``gaussian``, ``halton``, ``cross_entropy``) keep to when the domain declares
#: no ``solution_bounds``.
DEFAULT_BOX: tuple[float, float] = (-1.0, 1.0)
#: ``cross_entropy``: the share of each batch its distribution is refitted to (a constant, not a config key).
CROSS_ENTROPY_ELITE_FRACTION = 0.2
#: ``map_elites``: batches of uniform random solutions before it mutates, the paper's 4 (1 and 2 were no better per
#: evaluation and behind at equal CPU time: docs/DECISIONS.md).
MAP_ELITES_RANDOM_BATCHES = 4
#: ``cma_me``: the paper's two-stage improvement ranking.
CMA_ME_RANKER = "2imp"
#: Emitters that start from a point of their own (CMA-ES from the origin) and read the archive they add to, to rank
#: their solutions and to restart from its elites. The others start from the domain's random levels or never read
#: the archive (see :data:`EMITTERS`).
EMITTERS_WITH_OWN_START: frozenset[str] = frozenset({"cma_me"})

#: ``predict(solutions) -> (objective (n,), measures (n, m), extra fields {name: (n, ...)})``.
Predictor = Callable[[np.ndarray], tuple[np.ndarray, np.ndarray, Mapping[str, np.ndarray]]]


def emitter_seeds(seed: int | None, n: int) -> list[int | None]:
    """Independent per-emitter seeds derived from one run seed (``None`` stays unseeded)."""
    if seed is None:
        return [None] * n
    return [int(child.generate_state(1)[0]) for child in np.random.SeedSequence(seed).spawn(n)]


def _map_elites(archive: ArchiveBase, config: QDConfig, solution_dim: int, random_solutions: Sampler,
                seed: int | None, bounds: tuple[float, float] | None) -> EmitterBase:
    return MapElitesBitmapEmitter(archive, solution_dim=solution_dim, batch_size=config.batch_size,
                                  mutation_cells=config.mutation_cells,
                                  initial_random_batches=MAP_ELITES_RANDOM_BATCHES, seed=seed)


def _cma_me(archive: ArchiveBase, config: QDConfig, solution_dim: int, random_solutions: Sampler,
            seed: int | None, bounds: tuple[float, float] | None) -> EmitterBase:
    # CMA-ME's improvement emitter (SPEC: CMA-ME): CMA-ES from the origin, two-stage improvement ranking. Unbounded even
    # where the domain has a box: pyribs' CMA-ES redraws every solution outside the box until none is, which after
    # its step size has grown went on for hundreds of rounds in a gym audit; such a domain clips when it decodes.
    return EvolutionStrategyEmitter(archive, x0=np.zeros(solution_dim), sigma0=config.sigma0, ranker=CMA_ME_RANKER,
                                    batch_size=config.batch_size, seed=seed)


def _random(archive: ArchiveBase, config: QDConfig, solution_dim: int, random_solutions: Sampler,
            seed: int | None, bounds: tuple[float, float] | None) -> EmitterBase:
    return RandomEmitter(archive, sampler=random_solutions, batch_size=config.batch_size, seed=seed)


def _gaussian(archive: ArchiveBase, config: QDConfig, solution_dim: int, random_solutions: Sampler,
              seed: int | None, bounds: tuple[float, float] | None) -> EmitterBase:
    # MAP-Elites with Gaussian mutation (pyribs' own): while the archive is empty it returns its initial
    # solutions, a batch of the domain's random ones (pyribs takes them instead of an x0, not beside one),
    # then elites plus N(0, sigma0) noise, clipped to the box.
    initial = random_solutions(config.batch_size, np.random.default_rng(np.random.SeedSequence(seed).spawn(1)[0]))
    return GaussianEmitter(archive, sigma=config.sigma0, initial_solutions=initial,
                           bounds=[bounds or DEFAULT_BOX] * solution_dim, batch_size=config.batch_size, seed=seed)


def _halton(archive: ArchiveBase, config: QDConfig, solution_dim: int, random_solutions: Sampler,
            seed: int | None, bounds: tuple[float, float] | None) -> EmitterBase:
    return HaltonEmitter(archive, bounds=bounds or DEFAULT_BOX, batch_size=config.batch_size, seed=seed)


def _cross_entropy(archive: ArchiveBase, config: QDConfig, solution_dim: int, random_solutions: Sampler,
                   seed: int | None, bounds: tuple[float, float] | None) -> EmitterBase:
    return CrossEntropyEmitter(archive, bounds=bounds or DEFAULT_BOX, batch_size=config.batch_size,
                               elite_fraction=CROSS_ENTROPY_ELITE_FRACTION, seed=seed)


#: One emitter of each ``qd.emitter`` name: ``build(archive, config, solution_dim, random_solutions, seed, bounds)``,
#: ``bounds`` the domain's ``solution_bounds`` or ``None``. Its keys are the config's
#: :data:`~dsage_ray.config.EmitterName`.
EMITTERS: dict[EmitterName, Callable[[ArchiveBase, QDConfig, int, Sampler, int | None, tuple[float, float] | None],
                                     EmitterBase]] = {
    "map_elites": _map_elites,
    "cma_me": _cma_me,
    "random": _random,
    "gaussian": _gaussian,
    "halton": _halton,
    "cross_entropy": _cross_entropy,
}


def make_emitters(
    archive: ArchiveBase,
    *,
    config: QDConfig,
    solution_dim: int,
    random_solutions: Sampler,
    seed: int | None,
    bounds: tuple[float, float] | None = None,
) -> list[EmitterBase]:
    """``config.num_emitters`` emitters of kind ``config.emitter``, each with its own derived seed.

    Args:
        bounds: The domain's ``solution_bounds``, ``(low, high)`` in every dimension, or ``None`` (unbounded).
            ``cma_me`` keeps to them when given; ``gaussian``, ``halton`` and ``cross_entropy`` keep to them,
            or to :data:`DEFAULT_BOX` when ``None``; ``map_elites`` and ``random`` ignore them.

    Raises:
        ValueError: Unknown ``config.emitter``, ``solution_dim`` not matching the archive, or bad ``bounds``.
    """
    if solution_dim != archive.solution_dim:
        raise ValueError(f"solution_dim {solution_dim} does not match archive.solution_dim {archive.solution_dim}")
    if bounds is not None:
        bounds = check_box(bounds)
    if config.emitter not in EMITTERS:
        raise ConfigError(f"qd.emitter: unknown emitter {config.emitter!r} (known: {', '.join(EMITTERS)})"
                          f"{did_you_mean(config.emitter, EMITTERS)}")
    build = EMITTERS[config.emitter]
    return [build(archive, config, solution_dim, random_solutions, s, bounds)
            for s in emitter_seeds(seed, config.num_emitters)]


def make_scheduler(
    archive: ArchiveBase,
    *,
    config: QDConfig,
    solution_dim: int,
    random_solutions: Sampler,
    seed: int | None,
    bounds: tuple[float, float] | None = None,
    result_archive: ArchiveBase | None = None,
) -> Scheduler:
    """A pyribs scheduler over :func:`make_emitters` (``bounds``: see there); one :meth:`~Scheduler.ask` yields
    ``num_emitters × batch_size`` solutions. With a ``result_archive`` other than ``archive``, the emitters read
    ``archive`` and every solution told enters both."""
    emitters = make_emitters(
        archive, config=config, solution_dim=solution_dim, random_solutions=random_solutions, seed=seed,
        bounds=bounds,
    )
    return _scheduler(archive, emitters, result_archive)


def reopened_scheduler(scheduler: Scheduler) -> Scheduler:
    """A scheduler over ``scheduler``'s archives and emitters with no ask pending: it closes an ask/tell cycle whose
    batch cannot be told (pyribs needs the whole batch it asked for); the emitters never learn from that batch."""
    return _scheduler(scheduler.archive, scheduler.emitters, scheduler.result_archive)


def _scheduler(archive: ArchiveBase, emitters: list[EmitterBase], result_archive: ArchiveBase | None) -> Scheduler:
    # pyribs adds every solution told to its result archive besides its archive: the same one would get it twice.
    return Scheduler(archive, emitters, result_archive=None if result_archive is archive else result_archive)


#: Emitters that run pyribs' just-in-time compiled (numba) CMA-ES code.
COMPILED_EMITTERS: frozenset[str] = frozenset({"cma_me"})
#: Ask-tell rounds of :func:`compile_emitters`: enough that CMA-ES has updated its distribution (its ask then mixes
#: a float64 mean with the solutions' type, a signature numba compiles again; one round leaves it to the run).
COMPILE_ROUNDS = 10
#: Emitters, by solution type, whose pyribs code this process has compiled (:func:`compile_emitters`).
_COMPILED: set[tuple[str, str]] = set()


def compile_emitters(*, config: QDConfig, solution_dim: int, solution_dtype: Any, random_solutions: Sampler) -> bool:
    """Compiles, once per process, the just-in-time (numba) code of pyribs' CMA-ES that the configured emitter runs,
    on a throwaway archive: a process's first CMA-ME inner loop otherwise spends seconds compiling (7.3 s of 7.9
    on the CartPole fault task), which is no cost of the search's iterations and made ``search = "auto"`` take
    that task's first surrogate iteration for four times its random level's cost. Nothing of the run is read or
    changed (its own seed and archive, of the run's solution type: numba compiles per type).

    Returns:
        Whether it compiled (False: the emitter has no such code, or this process compiled it already).
    """
    key = (config.emitter, np.dtype(solution_dtype).str)
    if config.emitter not in COMPILED_EMITTERS or key in _COMPILED:
        return False
    from ribs.archives import GridArchive

    archive = GridArchive(solution_dim=solution_dim, dims=(2, 2), ranges=[(0.0, 1.0), (0.0, 1.0)], seed=0,
                          solution_dtype=solution_dtype)
    scheduler = make_scheduler(archive, config=dataclasses.replace(config, num_emitters=1), solution_dim=solution_dim,
                               random_solutions=random_solutions, seed=0)
    rng = np.random.default_rng(0)
    for _ in range(COMPILE_ROUNDS):
        count = len(scheduler.ask())
        scheduler.tell(rng.random(count), rng.random((count, 2)))
    _COMPILED.add(key)
    return True


@dataclasses.dataclass
class InnerLoopTimings:
    """Where the inner loop's wall time went.

    Attributes:
        iterations: ask → predict → tell rounds run.
        solutions: Solutions predicted in total.
        ask_s: Seconds in ``scheduler.ask`` (pyribs).
        predict_s: Seconds in ``predict`` (the surrogate).
        tell_s: Seconds in ``scheduler.tell`` (pyribs: archive insertion, emitter updates).
    """

    iterations: int = 0
    solutions: int = 0
    ask_s: float = 0.0
    predict_s: float = 0.0
    tell_s: float = 0.0

    @property
    def overhead_ms_per_iteration(self) -> float:
        """pyribs' own cost (ask + tell) per iteration, in milliseconds."""
        return 1e3 * (self.ask_s + self.tell_s) / max(self.iterations, 1)

    def to_dict(self) -> dict[str, Any]:
        return {**dataclasses.asdict(self), "overhead_ms_per_iteration": self.overhead_ms_per_iteration}


def run_inner_loop(
    scheduler: Scheduler,
    predict: Predictor,
    iterations: int,
    progress: Callable[[int], Any] | None = None,
) -> InnerLoopTimings:
    """Runs ``iterations`` ask → predict → tell rounds, filling ``scheduler.archive``.

    Args:
        scheduler: From :func:`make_scheduler`, usually on a fresh surrogate archive.
        predict: Returns objectives, measures and extra fields (e.g. ``{"occupancy": ...}``) for a
            batch of solutions; extra fields must match the archive's extra fields.
        iterations: Rounds to run.
        progress: Called with ``1`` after every round, e.g. ``tqdm(total=iterations).update``.

    Returns:
        Timings split between pyribs and the predictor.
    """
    timings = InnerLoopTimings()
    clock = time.perf_counter
    for _ in range(iterations):
        t0 = clock()
        solutions = scheduler.ask()
        t1 = clock()
        objective, measures, extra = predict(solutions)
        t2 = clock()
        scheduler.tell(objective, measures, **extra)
        t3 = clock()
        timings.iterations += 1
        timings.solutions += len(solutions)
        timings.ask_s += t1 - t0
        timings.predict_s += t2 - t1
        timings.tell_s += t3 - t2
        if progress is not None:
            progress(1)
    return timings
