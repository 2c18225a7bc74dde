"""Which candidates are worth a real evaluation, by the QD-score they are expected to add per expected cost
(``selection.screen_gain``; not in the paper).

A cheap estimate of a candidate (a surrogate's prediction, a one-episode screen) says where it lands, but not
how far off that tends to be. The estimate's errors on the levels recently evaluated do. :func:`expected_outcomes`
treats them as the distribution of a candidate's true outcome: the candidate's estimate plus the error of each
of the ``neighbours`` recent levels whose *estimated* measures were closest to its own (so an error that depends
on the estimate, e.g. short paths being screened well, carries over). Each such sample lands in a ground-truth
cell and adds what :class:`~ribs.archives.GridArchive` would add to the QD-score there; the mean over the samples
is the candidate's expected gain.

Evaluations do not all cost the same: a Maze evaluation steps the agent about as many times as its mean path
length, so a level the agent solves in 20 steps costs about an eighth of one it fails. With an
:class:`EvaluationCost` the same neighbours' real measures say what a candidate's evaluation will cost, and the
gain is counted per evaluation of average cost (docs/DECISIONS.md: the ranked screen).

Choosing the surrogate's picks the same way (the removed ``dsage_gain`` variant) was level with uniform
downsampling (docs/DECISIONS.md).
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np
from ribs.archives import GridArchive



@dataclasses.dataclass
class PickErrors:
    """What the surrogate predicted for its most recent evaluated picks, and what they scored.

    Attributes:
        window: How many of the latest picks are kept.
        predicted: ``(n, 1 + M)``: predicted objective, then the M predicted measures.
        actual: ``(n, 1 + M)``: the real objective and measures, same order.
    """

    window: int
    predicted: np.ndarray = dataclasses.field(default_factory=lambda: np.empty((0, 0)))
    actual: np.ndarray = dataclasses.field(default_factory=lambda: np.empty((0, 0)))

    def __post_init__(self) -> None:
        if self.window < 1:
            raise ValueError(f"window must be positive (got {self.window})")

    def __len__(self) -> int:
        return len(self.predicted)

    def add(self, *, predicted_objective: np.ndarray, predicted_measures: np.ndarray, objective: np.ndarray,
            measures: np.ndarray) -> None:
        """Appends evaluated picks (row i of each array is pick i), then keeps the latest :attr:`window`.

        Raises:
            ValueError: The arrays do not describe the same picks, or the number of measures changed.
        """
        predicted = np.column_stack([np.asarray(predicted_objective, np.float64).reshape(-1),
                                     np.asarray(predicted_measures, np.float64).reshape(len(predicted_measures), -1)])
        actual = np.column_stack([np.asarray(objective, np.float64).reshape(-1),
                                  np.asarray(measures, np.float64).reshape(len(measures), -1)])
        if predicted.shape != actual.shape:
            raise ValueError(f"predictions {predicted.shape} and results {actual.shape} differ in shape")
        if len(self) and predicted.shape[1] != self.predicted.shape[1]:
            raise ValueError(f"picks have {predicted.shape[1] - 1} measures, earlier ones {self.predicted.shape[1] - 1}")
        if len(predicted) == 0:
            return
        if len(self):
            predicted, actual = np.concatenate([self.predicted, predicted]), np.concatenate([self.actual, actual])
        self.predicted, self.actual = predicted[-self.window:], actual[-self.window:]

    def state_dict(self) -> dict[str, Any]:
        """Plain arrays, for a checkpoint."""
        return {"window": self.window, "predicted": self.predicted.copy(), "actual": self.actual.copy()}

    @classmethod
    def from_state_dict(cls, state: dict[str, Any]) -> "PickErrors":
        return cls(window=int(state["window"]), predicted=np.asarray(state["predicted"], np.float64),
                   actual=np.asarray(state["actual"], np.float64))


@dataclasses.dataclass(frozen=True)
class EvaluationCost:
    """What an evaluation costs: ``offset + x``, where ``x`` is a measure it grows with (e.g. the Maze's mean
    path length, since the simulator steps the agent that many times per episode).

    Attributes:
        measure: Index of the measure among the archive's measures.
        offset: The cost of an evaluation whose ``x`` is 0, in ``x``'s units (resetting and building the
            level); must be positive.
    """

    measure: int
    offset: float

    def __post_init__(self) -> None:
        if self.offset <= 0:
            raise ValueError(f"cost offset must be positive (got {self.offset})")


@dataclasses.dataclass(frozen=True)
class Outcomes:
    """What :func:`expected_outcomes` expects of each candidate.

    Attributes:
        gain: The QD-score it is expected to add.
        cost: What its evaluation is expected to cost, relative to the mean of the recent picks
            (all ones without an :class:`EvaluationCost`).
    """

    gain: np.ndarray
    cost: np.ndarray

    @property
    def gain_per_cost(self) -> np.ndarray:
        """The QD-score expected per evaluation of average cost."""
        return self.gain / self.cost


def expected_outcomes(
    objective: np.ndarray,
    measures: np.ndarray,
    *,
    ground_truth_archive: GridArchive,
    errors: PickErrors,
    neighbours: int,
    cost: EvaluationCost | None = None,
    chunk: int = 1024,
) -> Outcomes:
    """The QD-score each candidate is expected to add to ``ground_truth_archive``, and what it would cost.

    A sample (see the module doc) that lands in an empty cell adds its objective minus the archive's
    QD-score offset; one that lands in an occupied cell adds how much it beats the elite there, if it
    does. Samples outside the measure ranges land in the edge cells, as the archive would put them.
    The expected cost is that of the same neighbours' real evaluations.

    Args:
        objective: ``(n,)`` predicted objectives of the candidates.
        measures: ``(n, M)`` predicted measures.
        ground_truth_archive: The archive real evaluations enter.
        errors: Recent picks' predictions and results; empty: the predictions are taken as exact.
        neighbours: How many recent picks, nearest in predicted measures (scaled by the archive's
            ranges), lend their errors to a candidate; all of them if fewer are held.
        cost: How an evaluation's cost follows from its measures; None: every evaluation costs the same.
        chunk: Candidates scored at a time (bounds memory at ``chunk × len(errors)`` distances).

    Raises:
        ValueError: ``neighbours < 1``, or the shapes do not match the archive.
    """
    objective = np.asarray(objective, np.float64).reshape(-1)
    measures = np.asarray(measures, np.float64).reshape(len(objective), -1)
    dim = ground_truth_archive.measure_dim
    if measures.shape[1] != dim or (len(errors) and errors.predicted.shape[1] != 1 + dim):
        raise ValueError(f"the archive has {dim} measures; candidates have {measures.shape[1]}, "
                         f"recent picks {errors.predicted.shape[1] - 1 if len(errors) else '-'}")
    if neighbours < 1:
        raise ValueError(f"neighbours must be positive (got {neighbours})")
    if cost is not None and not 0 <= cost.measure < dim:
        raise ValueError(f"cost measure index {cost.measure} is not one of the archive's {dim} measures")
    cell_objective = _cell_objectives(ground_truth_archive)
    if len(errors) == 0:
        # Before any pick has been evaluated there are no errors to sample: take the predictions at their
        # word, and the cost from the predicted measure relative to the candidates' mean.
        gains = _added(ground_truth_archive, cell_objective, objective, measures)
        costs = np.ones(len(objective))
        if cost is not None and len(objective):
            own = np.maximum(cost.offset + measures[:, cost.measure], 0.0)
            costs = own / max(own.mean(), 1e-12)
        return Outcomes(gain=gains, cost=np.maximum(costs, 1e-6))
    scale = np.asarray(ground_truth_archive.upper_bounds, np.float64) - np.asarray(ground_truth_archive.lower_bounds,
                                                                                   np.float64)
    known = errors.predicted[:, 1:] / scale
    residuals = errors.actual - errors.predicted
    if cost is None:
        spent = np.ones(len(errors))
    else:
        spent = np.maximum(cost.offset + errors.actual[:, 1 + cost.measure], 0.0)
    spent = spent / spent.mean()
    k = min(neighbours, len(errors))
    gains, costs = np.empty(len(objective)), np.empty(len(objective))
    for start in range(0, len(objective), chunk):
        part = slice(start, start + chunk)
        distance = (((measures[part] / scale)[:, None, :] - known[None, :, :]) ** 2).sum(axis=2)
        nearest = np.argpartition(distance, k - 1, axis=1)[:, :k] if k < len(errors) else \
            np.broadcast_to(np.arange(len(errors)), distance.shape)
        sampled = residuals[nearest]  # (chunk, k, 1 + M)
        sample_objective = objective[part, None] + sampled[:, :, 0]
        sample_measures = measures[part, None, :] + sampled[:, :, 1:]
        gains[part] = _added(ground_truth_archive, cell_objective, sample_objective, sample_measures).mean(axis=1)
        costs[part] = spent[nearest].mean(axis=1)
    # A neighbourhood of evaluations that cost nothing would make any gain infinitely cheap.
    return Outcomes(gain=gains, cost=np.maximum(costs, 1e-6))


def _added(archive: GridArchive, cell_objective: np.ndarray, objective: np.ndarray, measures: np.ndarray) -> np.ndarray:
    """What each outcome (``objective``: any shape S, ``measures``: S + (M,)) would add to the archive's QD-score."""
    cells = archive.index_of(measures.reshape(-1, measures.shape[-1])).reshape(objective.shape)
    incumbent = cell_objective[cells]
    empty = np.isnan(incumbent)
    return np.where(empty, objective - archive.qd_score_offset,
                    np.maximum(objective - np.where(empty, 0.0, incumbent), 0.0))


def _cell_objectives(archive: GridArchive) -> np.ndarray:
    """The objective of every cell's elite, NaN where a cell is empty."""
    cells = np.full(archive.cells, np.nan)
    data = archive.data(["index", "objective"])
    cells[np.asarray(data["index"], np.int64)] = data["objective"]
    return cells
