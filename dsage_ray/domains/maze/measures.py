"""Named measures and objectives over a :class:`~dsage_ray.domains.maze.evaluate.MazeEvaluation`.

Configs name them (``MazeConfig.measures``, ``MazeConfig.objective``); each measure also knows its
natural range for a level size, which is the default ground-truth archive range. An objective takes
the audited agent's evaluation and, for the objectives in :data:`NEEDS_REFERENCE`, the reference
agent's evaluation of the same level with the same seed.
"""

from __future__ import annotations

import dataclasses
from typing import Callable

import numpy as np

from dsage_ray.domains.maze.evaluate import MazeEvaluation
from dsage_ray.domains.maze.level import max_steps_for


@dataclasses.dataclass(frozen=True)
class Measure:
    """A behaviour descriptor.

    Attributes:
        name: The config name.
        fn: Evaluation → value.
        natural_range: ``(height, width)`` → ``(low, high)``.
    """

    name: str
    fn: Callable[[MazeEvaluation], float]
    natural_range: Callable[[int, int], tuple[float, float]]


MEASURES: dict[str, Measure] = {
    m.name: m
    for m in (
        Measure("num_walls", lambda e: float(e.num_walls), lambda h, w: (0.0, float(h * w))),
        Measure("mean_path_length", lambda e: e.mean_path_length, lambda h, w: (0.0, float(max_steps_for(h, w)))),
        Measure("explored_fraction", lambda e: e.explored_fraction, lambda h, w: (0.0, 1.0)),
        Measure("repeated_visits", lambda e: e.repeated_visits, lambda h, w: (0.0, float(max_steps_for(h, w)))),
        Measure("optimal_path_length", lambda e: float(e.optimal_path_length), lambda h, w: (0.0, float(h * w))),
        Measure("success_rate", lambda e: e.success_rate, lambda h, w: (0.0, 1.0)),
    )
}


def _validity(e: MazeEvaluation, reference: MazeEvaluation | None = None) -> float:
    return 1.0 if e.valid else 0.0


def _failure_rate(e: MazeEvaluation, reference: MazeEvaluation | None = None) -> float:
    return 1.0 - e.success_rate if e.valid else 0.0


def _regret(e: MazeEvaluation, reference: MazeEvaluation | None = None) -> float:
    """Mean excess path length, scaled so the optimal path scores 0 and a failure 1."""
    if not e.valid:
        return 0.0
    excess = (e.episode_lengths - e.optimal_path_length) / (e.max_steps - e.optimal_path_length)
    return float(np.mean(excess))


def regression_score(success_rate: float, reference_success_rate: float) -> float:
    """The ``regression`` objective of a valid level: ``(1 + Δ) / 2`` with ``Δ = reference − new``.

    ``Δ`` is the difference of success rates of the two agents on the same level, seeds and episodes, in
    ``[-1, 1]``. QD archives and the QD score want a non-negative objective, and the search wants every
    valid level to rank: the affine map to ``[0, 1]`` keeps the order of ``Δ`` everywhere, so 0.5 is "no
    difference", 1 "the reference always succeeds where the new agent always fails" and 0 the opposite.
    A clipped ``max(Δ, 0)`` would give most levels of two similar agents the same 0 and leave the search
    (and the surrogate it trains) nothing to climb until it stumbled on a regression. Invalid levels
    score 0, the bottom of the scale, as in the other audit objectives.
    """
    return (1.0 + float(reference_success_rate) - float(success_rate)) / 2.0


def _regression(e: MazeEvaluation, reference: MazeEvaluation | None = None) -> float:
    if not e.valid:
        return 0.0
    if reference is None:
        raise ValueError("the 'regression' objective needs the reference agent's evaluation of the level")
    return regression_score(e.success_rate, reference.success_rate)


#: Objective name → ``fn(evaluation, reference=None)``.
OBJECTIVES: dict[str, Callable[..., float]] = {
    "validity": _validity,
    "failure_rate": _failure_rate,
    "regret": _regret,
    "regression": _regression,
}
#: Objectives that compare the audited agent with a reference agent (``MazeConfig.reference``).
NEEDS_REFERENCE = frozenset({"regression"})


def get_measure(name: str) -> Measure:
    """The measure called ``name``; ValueError listing the known ones otherwise."""
    try:
        return MEASURES[name]
    except KeyError:
        raise ValueError(f"unknown maze measure {name!r} (known: {sorted(MEASURES)})") from None


def get_objective(name: str) -> Callable[..., float]:
    """The objective called ``name``; ValueError listing the known ones otherwise."""
    try:
        return OBJECTIVES[name]
    except KeyError:
        raise ValueError(f"unknown maze objective {name!r} (known: {sorted(OBJECTIVES)})") from None
