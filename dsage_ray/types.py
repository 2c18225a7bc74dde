"""Typed aliases and records shared by the algorithm, the domains and the Ray layer.

The algorithm core sees a domain only through :class:`Domain` and an :data:`Evaluator`;
everything a domain knows about agents and simulators stays behind those two names.
"""

from __future__ import annotations

import dataclasses
from typing import Any, Callable, Protocol, Sequence, runtime_checkable

import numpy as np

#: One candidate environment in the search space: a wall bitmap (Maze) or a GAN latent (Mario).
Solution = np.ndarray
#: A batch of solutions, shape ``(n, solution_dim)``.
Solutions = np.ndarray
#: Surrogate-model input for a batch of solutions, shape ``(n, channels, height, width)``, float32.
EncodedLevels = np.ndarray


@dataclasses.dataclass
class EvaluationResult:
    """What one real evaluation (agent simulated on one level) returns.

    Attributes:
        objective: The quantity the QD search maximises.
        measures: Behaviour descriptors, shape ``(num_measures,)``.
        occupancy: Ancillary agent-behaviour data (expected visits per cell), float32.
        info: Domain-specific extras (success rate, episode lengths, ...), JSON-serialisable.
        failed: True when the evaluation raised; ``error`` then holds the message.
        error: The error message of a failed evaluation.
    """

    objective: float
    measures: np.ndarray
    occupancy: np.ndarray
    info: dict[str, Any] = dataclasses.field(default_factory=dict)
    failed: bool = False
    error: str | None = None

    @classmethod
    def failure(cls, *, error: str, num_measures: int, occupancy_shape: tuple[int, ...]) -> "EvaluationResult":
        return cls(
            objective=0.0,
            measures=np.zeros(num_measures, dtype=np.float64),
            occupancy=np.zeros(occupancy_shape, dtype=np.float32),
            failed=True,
            error=error,
        )


@runtime_checkable
class Domain(Protocol):
    """A search space plus a way to evaluate one of its points for real.

    Implementations are built from a picklable domain config (see :mod:`dsage_ray.config`) so that
    every simulator process (a Ray actor, or the test process) can build its own copy and load
    its agent once.
    """

    name: str
    solution_dim: int
    measure_names: tuple[str, ...]
    #: ``[(low, high), ...]`` per measure: the ground-truth archive's bounds.
    measure_ranges: tuple[tuple[float, float], ...]
    #: Cells per measure in the ground-truth archive.
    archive_dims: tuple[int, ...]
    occupancy_shape: tuple[int, int]
    #: Channels of :meth:`encode`'s output.
    encoding_channels: int
    #: How archives store solutions (``int8`` for bitmaps keeps a 100k-elite archive small).
    solution_dtype: type

    def random_solutions(self, n: int, rng: np.random.Generator) -> Solutions:
        """Samples ``n`` solutions the way DR and the first outer iteration do."""

    def encode(self, solutions: Solutions) -> EncodedLevels:
        """One-hot levels for the surrogate model."""

    def evaluate(self, solution: Solution, seed: int) -> EvaluationResult:
        """Simulates the domain's agent on one level; deterministic for a given seed."""

    def render(self, solution: Solution, occupancy: np.ndarray | None) -> bytes:
        """A PNG of the level, with the occupancy overlaid when given."""


#: Evaluates a batch of solutions, one seed each, returning results in submission order.
Evaluator = Callable[[Solutions, Sequence[int]], list[EvaluationResult]]
