"""Typed aliases and records shared by the algorithm, the domains and the Ray layer.

The algorithm core sees a domain only through :class:`Domain` and an :data:`Evaluator`;
everything a domain knows about agents and simulators stays behind those two names.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
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
        info: Domain-specific extras (success rate, episode lengths, ...), JSON-serialisable. Only the
            domain reads them: the audit asks an :class:`AuditableDomain` for the numbers it needs.
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
    """A search space plus a way to evaluate one of its points for real: what every domain has.

    Implementations are built as ``Class(config=section)`` from the picklable config section their
    registration names (:mod:`dsage_ray.domains.registry`), so that every simulator process (a Ray
    actor, or the test process) can build its own copy and load its agent once. These are the
    members the runner and the Ray pool use.

    What only some domains can do is a capability of its own, a protocol checked with ``isinstance``:
    :class:`RenderableDomain` (pictures of levels), :class:`PreflightDomain` (loads its agents early),
    :class:`BoundedDomain` (the box continuous solutions live in), :class:`ScreenableDomain` (a cheap estimate
    of many levels) and :class:`CostModelDomain` (what an evaluation costs), :class:`PriorDomain` (a prior of a
    measure for the surrogate), :class:`LevelValuesDomain` (values of the level alone), :class:`WorkCountingDomain`
    (the work an evaluation did), :class:`AuditableDomain` (``dsage-ray audit``) and :class:`NominalDomain` (the
    audit's nominal check).
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
    #: The channel :meth:`encode` output is padded with when the surrogate pads a level to a square
    #: power of two (a channel no real cell uses keeps padding apart from floor or wall).
    encoding_pad_channel: int
    #: How archives store solutions (``int8`` for bitmaps keeps a 100k-elite archive small).
    solution_dtype: type

    def random_solutions(self, n: int, rng: np.random.Generator) -> Solutions:
        """Samples ``n`` solutions the way DR and the first outer iteration do."""

    def random_valid_solutions(self, n: int, rng: np.random.Generator) -> Solutions:
        """Samples ``n`` valid levels: the surrogate's held-out set (``experimental.holdout_levels``)."""

    def encode(self, solutions: Solutions) -> EncodedLevels:
        """One-hot levels for the surrogate model."""

    def evaluate(self, solution: Solution, seed: int) -> EvaluationResult:
        """Simulates the domain's agent on one level; deterministic for a given seed."""


# ------------------------------------------------------------------------------------ optional capabilities


@runtime_checkable
class RenderableDomain(Protocol):
    """A domain that draws its levels: the run folder's elite pictures and TensorBoard's images."""

    def render(self, solution: Solution, occupancy: np.ndarray | None) -> bytes:
        """A PNG of the level, with the occupancy overlaid when given."""


@runtime_checkable
class PreflightDomain(Protocol):
    """A domain that can load what a search needs before it starts, so that a bad agent fails first."""

    def preflight(self) -> None:
        """Loads whatever a search needs (agents, simulators) now, so a bad one fails before any search."""


@runtime_checkable
class BoundedDomain(Protocol):
    """A continuous domain whose solutions live in a box.

    The QD emitters keep to it: ``cma_me`` resamples outside it, ``gaussian``, ``halton`` and ``cross_entropy``
    search it (they search [-1, 1] where a domain declares none), and elite mutants are clipped to it
    (:func:`dsage_ray.qd.optimizer.make_emitters`).
    """

    #: ``(low, high)`` in every dimension (e.g. ``(-1.0, 1.0)``; the domain clips what lies beyond when it
    #: decodes); None: unbounded.
    solution_bounds: tuple[float, float] | None


def solution_bounds(domain: Domain) -> tuple[float, float] | None:
    """The box ``domain``'s solutions live in (:class:`BoundedDomain`), or None: unbounded."""
    return domain.solution_bounds if isinstance(domain, BoundedDomain) else None


@runtime_checkable
class ScreenableDomain(Protocol):
    """A domain with a cheap estimate of many levels, which ``selection.screen_episodes`` screens picks with
    (:mod:`dsage_ray.core.screening`; Maze has one). The screening keys apply only to such a domain, which its
    registration declares (``DomainSpec.screenable``) so that a config is checked without importing it."""

    def screen(self, solutions: Solutions, *, episodes: int, seed: int, precision: str) -> list[EvaluationResult]:
        """Estimates each level with ``episodes`` episodes, ``precision`` ``"fp32"`` or ``"bf16"`` (the agent's
        ``reduced_precision`` copy, where it has one)."""


@runtime_checkable
class CostModelDomain(Protocol):
    """A domain whose evaluations cost in proportion to one of its measures; ``selection.screen_gain`` ranks
    screened levels by expected gain per cost with it (:mod:`dsage_ray.qd.gain`)."""

    #: The measure an evaluation's cost grows in proportion to, and the cost of an evaluation at 0 in that
    #: measure's units (Maze: ``("mean_path_length", 200.0)``); None: every evaluation costs the same.
    evaluation_cost: tuple[str, float] | None


@runtime_checkable
class PriorDomain(Protocol):
    """A domain with parameter-free priors of some measures, which ``surrogate.prior_measure`` blends into the
    surrogate's prediction (:func:`dsage_ray.surrogate.surrogate.domain_prior`; Maze has one for
    ``mean_path_length``)."""

    def surrogate_prior(self, measure: str) -> Callable[[EncodedLevels], np.ndarray] | None:
        """The prior of ``measure`` from the encoded levels ``(n, C, S, S)`` → ``(n,)``; None: none for it."""


@runtime_checkable
class LevelValuesDomain(Protocol):
    """A domain some of whose values are functions of the level alone, which ``surrogate.exact_level_values``
    puts in place of the surrogate's predictions (:func:`dsage_ray.surrogate.surrogate.domain_level_values`)."""

    def level_values(self, encoded: EncodedLevels) -> dict[str, np.ndarray]:
        """``{name: (n,) array}`` read from encoded levels ``(n, C, S, S)``; keys are measure names or
        ``"objective"`` (Maze: ``num_walls``, ``optimal_path_length`` and the ``validity`` objective; Mario:
        ``sky_tiles``)."""


@runtime_checkable
class WorkCountingDomain(Protocol):
    """A domain that counts the work an evaluation did in units that do not depend on the machine (Maze:
    ``steps``; Mario: ``search_iterations``, ``ticks``); benchmarks read them."""

    work_names: tuple[str, ...]

    def work_counts(self, result: EvaluationResult) -> dict[str, float]:
        """``{name: count}`` for each of :attr:`work_names`, read from the result's ``info``."""


@runtime_checkable
class AuditableDomain(Domain, RenderableDomain, PreflightDomain, Protocol):
    """A domain ``dsage-ray audit`` can search and collect levels of, and ``dsage-ray compare`` can re-run
    two agents on (its registration's ``audit`` says which objectives, measures and agent by default, and
    which of the entries' numbers the report shows; its ``agents`` which agent specs it plays).

    The audit reads an evaluation only through these members, never its ``info``.

    Raising :class:`ValueError` (an :class:`~dsage_ray.errors.InputError`) from a hook ends the command
    with its message in one line.
    """

    @classmethod
    def audit_values(cls, *, agent: str, reference: str | None = None, objective: str | None = None,
                     measures: Sequence[str] | None = None) -> dict[str, Any]:
        """The dotted config keys of an audit of ``agent`` (against ``reference``, if the domain compares agents)."""

    @property
    def agent_spec(self) -> str:
        """The audited agent's spec."""

    @property
    def reference_spec(self) -> str | None:
        """The reference agent's spec of a regression audit, else None."""

    @property
    def episodes(self) -> int:
        """Episodes (or runs) per evaluation."""

    def is_valid(self, solution: Solution) -> bool:
        """Whether a level is playable; invalid ones never reach a collection."""

    def level_text(self, solution: Solution) -> str:
        """The level file of a solution, as the domain's own ``eval`` command reads it."""

    def success_rate(self, result: EvaluationResult) -> float:
        """The share of the evaluation's episodes (or runs) the agent solved, in ``[0, 1]``."""

    def reference_numbers(self, result: EvaluationResult) -> dict[str, float] | None:
        """In a regression audit, the reference agent's ``success_rate`` (and any of the registration's
        columns) from the same evaluation; None otherwise."""

    def entry_solution(self, entry: dict[str, Any], folder: Path) -> Solution:
        """The solution of a collection entry (``dsage-ray compare`` re-runs them), from its level file in
        ``folder`` or its own keys.

        Raises:
            ValueError: An entry whose level cannot be read back (a file that is not such a level, an
                entry written before the domain recorded what it needs).
        """

    def reproduce_command(self, level_file: str | Path, *, seed: int) -> str:
        """The shell command that re-runs this evaluation of ``level_file``."""

    def render_evaluation(self, solution: Solution, result: EvaluationResult, *, title: str | None = None,
                          occupancy_max: float | None = None) -> bytes:
        """A PNG of the level with what ``result`` recorded of the agent (occupancy, path)."""

    def collection_fields(self) -> dict[str, Any]:
        """The domain's settings at the top level of a collection."""

    def entry_fields(self, solution: Solution, result: EvaluationResult, *, level_file: str) -> dict[str, Any]:
        """The domain's own numbers of one collection entry: every key its registration's ``columns`` name."""


@dataclasses.dataclass(frozen=True, kw_only=True)
class NominalResult:
    """What the audited agent did on its domain's nominal level: the level it was trained for, with nothing varied.

    The audit plays it before every search (:mod:`dsage_ray.audit.nominal`), so that an agent played other than
    as trained (its observation preprocessing missing, another environment version) is caught before the search
    reports failures that are artefacts of the loader.

    Attributes:
        level: The nominal level in words, for the printed line and the report (``"CartPole-v1 as registered"``).
        return_name: What :attr:`mean_return` is in this domain (``"return"``, ``"MiniGrid reward"``,
            ``"completion"``), for the printed line.
        mean_return: The mean over the episodes of an episode's return.
        return_std: The sample standard deviation of the episodes' returns (0 for one episode).
        success_rate: The share of the episodes the domain's success test passed, in ``[0, 1]``.
        episodes: Episodes played (an A* run that is deterministic counts once).
        seed: The seed the episodes were played with.
        expected_return: The return the agent's own training record expects there
            (:attr:`~dsage_ray.agents.base.Agent.expected_return`), or None.
        expected_return_source: Where :attr:`expected_return` was read from.
        causes: The likely causes of a failing check in this domain, for the one-line stop.
    """

    level: str
    return_name: str = "return"
    mean_return: float
    return_std: float
    success_rate: float
    episodes: int
    seed: int
    expected_return: float | None = None
    expected_return_source: str = ""
    causes: str = ""


@runtime_checkable
class NominalDomain(Protocol):
    """An optional capability of an :class:`AuditableDomain`: a nominal level to play the agent on before a search.

    Gym: the environment as registered (only the space's fixed ``gym.make`` keywords), or the values of the space's
    ``[nominal]`` table; Maze: an open room; Mario: a flat level. A domain without one skips the check.
    """

    def play_nominal(self, *, seed: int) -> NominalResult:
        """Plays the audited agent for a few episodes of the nominal level, deterministic for ``seed``.

        Raises:
            ValueError: The agent or the level cannot be played (one line).
        """


#: Evaluates a batch of solutions, one seed each, returning results in submission order. An evaluator may
#: also offer ``evaluate_until(solutions, seeds, *, deadline, progress)`` (stop starting levels once
#: ``time.perf_counter()`` passes ``deadline``; return the evaluated prefix) and ``runs_elsewhere = True``
#: (its simulators are other processes, so a pipelined run overlaps them); see
#: :mod:`dsage_ray.core.evaluation`.
Evaluator = Callable[[Solutions, Sequence[int]], list[EvaluationResult]]
