"""What the outer loop is written against: a :class:`Proposer`, the :class:`Proposal` it makes, its agent
:class:`Simulation` (the real evaluations) and the :class:`EvaluatedBatch` it learns from.

One outer iteration (:meth:`dsage_ray.core.runner.DSAGE.step`) is ``propose`` → ``evaluate`` → ``learn``. The
strategies are in :mod:`dsage_ray.core.proposers` (DSAGE, a direct QD search); :mod:`dsage_ray.core.prefetch` and
:mod:`dsage_ray.core.auto_proposer` wrap DSAGE (``pipeline = true``, ``search = "auto"``).
"""

from __future__ import annotations

import dataclasses
import time
from typing import TYPE_CHECKING, Any, Callable, Mapping, Protocol, Sequence

import numpy as np

from dsage_ray.core.evaluation import PendingEvaluation
from dsage_ray.types import Domain, EvaluationResult, Evaluator, Solutions

if TYPE_CHECKING:
    from dsage_ray.surrogate.surrogate import Prediction

#: Called with (phase, done, total) while a step runs; the CLI turns it into progress bars.
ProgressCallback = Callable[[str, int, int], None]


@dataclasses.dataclass
class Proposal:
    """An iteration's candidates, with what choosing them reported."""

    solutions: Solutions
    metrics: dict[str, float] = dataclasses.field(default_factory=dict)
    #: Seconds per phase (``train``, ``exploit``, ``select``, ``holdout``).
    times: dict[str, float] = dataclasses.field(default_factory=dict)
    #: What the surrogate that chose the solutions predicted for them (None: chosen without one). Kept
    #: with the proposal because in a pipelined run the surrogate has trained again by the time the
    #: results arrive, and the selected batch's error is that of the model that selected it.
    predicted: "Prediction | None" = None
    #: ``(n, 1 + M)``: each solution's screened objective and measures, NaN for one not screened (None: no screen).
    #: What the screen errs by on them is learnt once they are evaluated (``selection.screen_gain``).
    screened: np.ndarray | None = None

    def take(self, indices: "list[int] | slice") -> "Proposal":
        """The proposal of these solutions only, in this order (their predictions and screened results with them)."""
        predicted = self.predicted
        if predicted is not None:
            predicted = dataclasses.replace(predicted, **{
                name: None if value is None else value[indices] for name, value in dataclasses.asdict(predicted).items()})
        return dataclasses.replace(self, solutions=self.solutions[indices], predicted=predicted,
                                   screened=None if self.screened is None else self.screened[indices])

    def state_dict(self) -> dict[str, Any]:
        """Plain arrays and dicts, for a checkpoint."""
        return dataclasses.asdict(self)

    @classmethod
    def from_state_dict(cls, state: dict[str, Any]) -> "Proposal":
        from dsage_ray.surrogate.surrogate import Prediction

        predicted = state.get("predicted")
        return cls(solutions=state["solutions"], metrics=dict(state["metrics"]), times=dict(state["times"]),
                   predicted=None if predicted is None else Prediction(**predicted), screened=state.get("screened"))


@dataclasses.dataclass(frozen=True)
class EvaluatedBatch:
    """What the real evaluation of a proposal returned, split into what succeeded.

    Attributes:
        solutions: The evaluated solutions (the proposal, cut to the remaining budget).
        results: One result per solution, failures included.
        ok: Indices of the successful results.
        objective, measures, occupancy: Of the successful results, stacked.
        complete: Every proposed solution was evaluated and succeeded (what a QD scheduler's ``tell`` needs).
        outer_iteration: The iteration that proposed them (0 is the first).
        predicted: The proposal's predictions for ``solutions`` (see :attr:`Proposal.predicted`).
        screened: The proposal's screened results for ``solutions`` (see :attr:`Proposal.screened`).
        seeds: Each solution's evaluation seed (empty where the caller did not say).
    """

    solutions: Solutions
    results: list[EvaluationResult]
    ok: list[int]
    objective: np.ndarray
    measures: np.ndarray
    occupancy: np.ndarray
    complete: bool
    outer_iteration: int
    predicted: "Prediction | None" = None
    screened: np.ndarray | None = None
    seeds: tuple[int, ...] = ()

    @classmethod
    def collect(cls, proposal: Proposal, results: list[EvaluationResult], *, domain: Domain,
                outer_iteration: int, seeds: "tuple[int, ...] | list[int]" = ()) -> "EvaluatedBatch":
        """The evaluated part of ``proposal``: its first ``len(results)`` solutions (a budget may cut it)."""
        evaluated = proposal.take(slice(0, len(results)))
        solutions, predicted = evaluated.solutions, evaluated.predicted
        ok = [i for i, r in enumerate(results) if not r.failed]
        return cls(
            solutions=solutions, results=results, ok=ok,
            objective=np.array([results[i].objective for i in ok], dtype=np.float64),
            measures=np.array([results[i].measures for i in ok], dtype=np.float64).reshape(
                len(ok), len(domain.measure_names)),
            occupancy=np.array([results[i].occupancy for i in ok], dtype=np.float32).reshape(
                (len(ok),) + tuple(domain.occupancy_shape)),
            complete=len(ok) == len(proposal.solutions), outer_iteration=outer_iteration, predicted=predicted,
            screened=evaluated.screened, seeds=tuple(seeds))


class Simulation:
    """The real evaluation of one outer iteration's proposal.

    Level ``i`` of the proposal is evaluated with ``seeds[i]`` (the run's evaluation ``evals + i``), whoever
    evaluates it, in whichever part and order: a proposer that evaluates some levels first, or drops the rest
    (``search = "auto"``), evaluates each level as one batch would. The results are kept by level as they come back;
    :meth:`batch` gives what was evaluated, in the proposal's order.

    Args:
        proposal: The iteration's proposal.
        evaluator: Evaluates levels for real.
        seeds: One per level to evaluate: the proposal within the evaluation budget.
        evals: Real evaluations spent before this iteration's.
        budget: The run's evaluation budget.
        deadline: The :func:`time.perf_counter` value at which the time budget runs out (None: no time budget): a
            batch under evaluation then stops, the levels under way finishing (``evaluate_prefix`` in
            :mod:`dsage_ray.core.evaluation`).
        progress: The run's progress callback (the ``evaluate`` bar).
        times: The iteration's seconds per phase so far; a proposer that works while the batch is out adds its
            phases (:meth:`add_times`).

    Attributes:
        solutions: The levels to evaluate: the proposal within the evaluation budget.
        results: The results so far, by level.
    """

    def __init__(self, *, proposal: Proposal, evaluator: Evaluator, seeds: Sequence[int], evals: int, budget: int,
                 deadline: float | None, progress: ProgressCallback | None = None,
                 times: Mapping[str, float] | None = None) -> None:
        self.proposal = proposal
        self.evaluator = evaluator
        self.seeds = list(seeds)
        self.solutions = proposal.solutions[:len(self.seeds)]
        self.evals = evals
        self.budget = budget
        self.deadline = deadline
        self.progress = progress
        self.times: dict[str, float] = dict(times or {})
        self.results: dict[int, EvaluationResult] = {}

    @property
    def count(self) -> int:
        """Levels to evaluate."""
        return len(self.solutions)

    def time_left(self) -> float | None:
        """Seconds of the time budget left now (None: no time budget)."""
        return None if self.deadline is None else self.deadline - time.perf_counter()

    def start(self, indices: "Sequence[int] | slice | None" = None, *, deadline: float | None = None) -> "Running":
        """Starts evaluating these levels (default: all), in the background where the evaluator's simulators run
        elsewhere (:class:`~dsage_ray.core.evaluation.PendingEvaluation`); ``deadline`` stops them earlier than
        the time budget does."""
        if indices is None:
            positions, solutions, seeds = list(range(self.count)), self.solutions, self.seeds
        elif isinstance(indices, slice):
            positions = list(range(self.count))[indices]
            solutions, seeds = self.solutions[indices], self.seeds[indices]
        else:
            positions = [int(i) for i in indices]
            solutions, seeds = self.solutions[positions], [self.seeds[i] for i in positions]
        if deadline is not None and self.deadline is not None:
            deadline = min(deadline, self.deadline)
        elif deadline is None:
            deadline = self.deadline
        return Running(self, positions, PendingEvaluation(self.evaluator, solutions, seeds, deadline=deadline,
                                                         progress=self._progress()))

    def evaluate(self, indices: "Sequence[int] | slice | None" = None, *,
                 deadline: float | None = None) -> list[EvaluationResult]:
        """Evaluates these levels (default: all) now; returns their results, a prefix of them where a deadline
        stopped them."""
        return self.start(indices, deadline=deadline).result()

    def add_times(self, times: Mapping[str, float]) -> None:
        """Adds these phases' seconds to the iteration's."""
        for phase, seconds in times.items():
            self.times[phase] = self.times.get(phase, 0.0) + seconds

    def batch(self, *, domain: Domain, outer_iteration: int) -> EvaluatedBatch:
        """What was evaluated, in the proposal's order: the proposal's first levels, or (where a proposer chose some
        of them) those it chose, with their predictions and screened results."""
        evaluated = sorted(self.results)
        proposal = self.proposal if evaluated == list(range(len(evaluated))) else self.proposal.take(evaluated)
        return EvaluatedBatch.collect(proposal, [self.results[i] for i in evaluated], domain=domain,
                                      outer_iteration=outer_iteration, seeds=[self.seeds[i] for i in evaluated])

    def _progress(self):
        """The evaluation bar's callback for the next part (the levels already evaluated count as done)."""
        if self.progress is None:
            return None
        start, budget, progress = self.evals + len(self.results), self.budget, self.progress
        return lambda done: progress("evaluate", start + done, budget)


class Running:
    """Levels of a :class:`Simulation` under evaluation; :meth:`result` waits for them and keeps their results."""

    def __init__(self, simulation: Simulation, positions: list[int], pending: PendingEvaluation) -> None:
        self.simulation = simulation
        self.positions = positions
        self.pending = pending

    @property
    def overlapped(self) -> bool:
        """Whether they are being evaluated in the background while the caller works."""
        return self.pending.overlapped

    def result(self) -> list[EvaluationResult]:
        """Their results (a prefix of them where a deadline stopped them), kept in the simulation too."""
        results = self.pending.result()
        self.simulation.results.update(zip(self.positions, results))
        return results


class Proposer(Protocol):
    """A strategy of the outer loop: propose solutions, have them evaluated, then learn from their real results.

    A strategy may subclass this for :meth:`evaluate`'s default (every level in one batch).
    """

    def propose(self, *, outer_iteration: int) -> Proposal:
        """The solutions to evaluate this iteration."""

    def evaluate(self, simulation: Simulation) -> None:
        """Has the proposal evaluated for real (:class:`Simulation`): all of it in one
        batch. A strategy that decides by what the evaluations cost evaluates it in parts, or only some of it."""
        simulation.evaluate()

    def learn(self, batch: EvaluatedBatch) -> dict[str, float]:
        """Adds the batch to the ground-truth archive and to what the proposer learns from; returns metrics."""

    def state_dict(self) -> dict[str, Any]:
        """The proposer's part of the run's checkpoint."""

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Restores :meth:`state_dict` (the whole checkpoint's dict is passed)."""


class ProposerWrapper(Proposer):
    """A proposer around another (:attr:`inner`), which does the work.

    What the runner reads of its proposer (the surrogate, its dataset, the held-out levels, the last predictions) is
    the inner proposer's, None where it has none (a direct search).
    """

    inner: Proposer

    @property
    def surrogate(self):
        return getattr(self.inner, "surrogate", None)

    @property
    def dataset(self):
        return getattr(self.inner, "dataset", None)

    @property
    def holdout(self):
        return getattr(self.inner, "holdout", None)

    @property
    def screen(self):
        return getattr(self.inner, "screen", None)

    @property
    def last_predictions(self) -> "tuple[np.ndarray, np.ndarray] | None":
        return getattr(self.inner, "last_predictions", None)
