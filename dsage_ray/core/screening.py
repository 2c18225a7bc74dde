"""The screen step of a selection (``selection.screen_episodes``; not in the paper), for DSAGE and MAP-Elites alike.

A run that screens builds one :class:`ScreenStep` from its config: the domain's cheap evaluation
(:func:`domain_screen`), and with ``selection.screen_gain`` the record of how the screen erred on the levels it
let through and the domain's cost model, which rank the candidates by expected gain per expected cost
(:mod:`dsage_ray.qd.gain`). DSAGE screens its picks and more surrogate elites (:meth:`ScreenStep.screen_picks`),
MAP-Elites a batch of its own mutants (:meth:`ScreenStep.keep`); both then teach it their real results
(:meth:`ScreenStep.learn`). The step's state is its error record, kept in the run's checkpoint.
"""

from __future__ import annotations

import time
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np
import torch

from dsage_ray.config import ConfigError, RunConfig
from dsage_ray.qd.gain import EvaluationCost, PickErrors
from dsage_ray.qd.screen import Screen, keep_screened, screen_picks
from dsage_ray.surrogate.surrogate import resolve_precision
from dsage_ray.types import CostModelDomain, Domain, ScreenableDomain, Solutions

if TYPE_CHECKING:
    from ribs.archives import GridArchive

    from dsage_ray.core.seeds import RunSeeds


class ScreenedResults(Protocol):
    """What :meth:`ScreenStep.learn` reads of an evaluated batch (:class:`~dsage_ray.core.proposers.EvaluatedBatch`)."""

    screened: np.ndarray | None
    ok: list[int]
    objective: np.ndarray
    measures: np.ndarray


class ScreenStep:
    """Screens candidates before their real evaluation and keeps those expected to add most to the ground truth.

    Args:
        config: The run's config (``selection.screen_episodes``, ``selection.screen_gain``, ``experimental.*``).
        domain: The domain, which must have a ``screen`` method.
        seeds: The run's seed streams (each screen draws its seed from them).

    Raises:
        ConfigError: The domain cannot screen.
    """

    def __init__(self, *, config: RunConfig, domain: Domain, seeds: "RunSeeds") -> None:
        self.screen: Screen = domain_screen(config, domain, seeds)
        self.pool = config.experimental.screen_pool
        self.neighbours = config.experimental.gain_neighbours
        self.window = config.experimental.gain_window
        #: The screen's errors on the levels it let through (``selection.screen_gain`` ranks by them; None: off).
        self.errors = PickErrors(window=self.window) if config.selection.screen_gain else None
        self.cost = evaluation_cost(config, domain)

    @classmethod
    def for_run(cls, *, config: RunConfig, domain: Domain, seeds: "RunSeeds") -> "ScreenStep | None":
        """The run's screen step, or None where ``selection.screen_episodes`` is 0."""
        return cls(config=config, domain=domain, seeds=seeds) if config.selection.screen_episodes else None

    def screen_picks(self, surrogate_archive: "GridArchive", picks: np.ndarray, ground_truth: "GridArchive", *,
                     rng: np.random.Generator, metrics: dict[str, float],
                     times: dict[str, float]) -> tuple[np.ndarray, np.ndarray]:
        """DSAGE: the surrogate-archive indices to evaluate instead of ``picks``, and their screened results.

        Adds the ``selection_screen*`` metrics and ``times["screen"]``.
        """
        tic = time.perf_counter()
        screened = screen_picks(surrogate_archive, picks, ground_truth, screen=self.screen, pool=self.pool, rng=rng,
                                errors=self.errors, neighbours=self.neighbours, cost=self.cost)
        times["screen"] = time.perf_counter() - tic
        metrics.update(screen_metrics(screened.screened, screened.new, screened.fallback, screened.expected_new))
        return screened.kept, screened.estimates

    def keep(self, candidates: Solutions, ground_truth: "GridArchive", *,
             limit: int) -> tuple[np.ndarray, np.ndarray, dict[str, float]]:
        """MAP-Elites: the positions of at most ``limit`` ``candidates`` to evaluate (the first ``limit`` where none
        would add), their screened results, and the ``selection_screen*`` metrics."""
        screened = keep_screened(candidates, ground_truth, screen=self.screen, limit=limit, errors=self.errors,
                                 neighbours=self.neighbours, cost=self.cost)
        fallback = len(screened.kept) == 0
        kept = np.arange(min(limit, len(candidates))) if fallback else screened.kept
        return kept, screened.estimates[kept], screen_metrics(len(candidates), screened.new, fallback,
                                                              screened.expected_new)

    def learn(self, batch: ScreenedResults) -> None:
        """Records how the screen erred on the batch's successful, screened solutions (where it ranks by them)."""
        if self.errors is None or batch.screened is None or not batch.ok:
            return
        estimates = batch.screened[batch.ok]
        screened = np.isfinite(estimates).all(axis=1)
        self.errors.add(predicted_objective=estimates[screened, 0], predicted_measures=estimates[screened, 1:],
                        objective=batch.objective[screened], measures=batch.measures[screened])

    def state_dict(self) -> dict[str, Any] | None:
        """The error record, for the run's checkpoint (None: nothing to keep)."""
        return None if self.errors is None else self.errors.state_dict()

    def load_state_dict(self, saved: dict[str, Any] | None) -> None:
        """Restores :meth:`state_dict` (a checkpoint without a record leaves a fresh one)."""
        if self.errors is not None:
            self.errors = PickErrors(window=self.window) if saved is None else PickErrors.from_state_dict(saved)


def screen_metrics(screened: int, new: int, fallback: bool, expected_new: float) -> dict[str, float]:
    """The ``selection_screen*`` metrics of one screened selection."""
    metrics = {"selection_screened": float(screened), "selection_screened_new": float(new),
               "selection_screen_fallback": float(fallback)}
    if np.isfinite(expected_new):
        metrics["selection_screen_expected_new"] = expected_new
    return metrics


def domain_screen(config: RunConfig, domain: Domain, seeds: "RunSeeds") -> Screen:
    """``selection.screen_episodes`` as a :data:`~dsage_ray.qd.screen.Screen` over ``domain.screen``.

    Each call draws its seed from the run's stream, so a screened run is as reproducible as any other.

    Raises:
        ConfigError: The domain has no ``screen`` (a domain passed in may not be the config's own).
    """
    episodes = config.selection.screen_episodes
    if not isinstance(domain, ScreenableDomain):
        raise ConfigError(f"selection.screen_episodes: the {domain.name!r} domain cannot screen levels (it has no "
                          "screen method; Maze has); set selection.screen_episodes = 0")
    precision = resolve_precision(config.experimental.screen_precision, torch.device("cpu"))

    def screen(solutions: Solutions) -> tuple[np.ndarray, np.ndarray]:
        seed = int(seeds.rng.integers(2**31 - 1))
        results = domain.screen(solutions, episodes=episodes, seed=seed, precision=precision)
        return (np.array([result.objective for result in results], dtype=np.float64),
                np.array([result.measures for result in results], dtype=np.float64).reshape(
                    len(results), len(domain.measure_names)))

    return screen


def evaluation_cost(config: RunConfig, domain: Domain) -> EvaluationCost | None:
    """The domain's cost model (its ``evaluation_cost``: a measure an evaluation's cost grows with, and the cost
    at 0 in that measure's units), where ``selection.screen_gain`` ranks by it; None: every evaluation costs the
    same (no ranking, no cost model, or the run does not measure the model's measure)."""
    model = domain.evaluation_cost if isinstance(domain, CostModelDomain) else None
    if not config.selection.screen_gain or model is None or model[0] not in domain.measure_names:
        return None
    measure, offset = model
    return EvaluationCost(measure=list(domain.measure_names).index(measure), offset=offset)
