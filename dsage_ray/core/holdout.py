"""Held-out levels: random valid levels evaluated for real once, to score the surrogate on levels it never trains on.

They are extra evaluations, counted as ``holdout_evals`` and never in ``evals``: they use their own
seed streams and never enter the dataset, the archive or the budget, so a run's search is the same
with or without them (``experimental.holdout_levels``; 0 turns them off).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Callable, Sequence

import numpy as np
from scipy import stats

from dsage_ray.core.evaluation import evaluate_with_retry
from dsage_ray.surrogate.dataset import Targets
from dsage_ray.surrogate.models import encode_solutions
from dsage_ray.types import Domain, EvaluationResult, Evaluator

if TYPE_CHECKING:
    from dsage_ray.core.seeds import RunSeeds
    from dsage_ray.surrogate import Surrogate

#: Called with (phase, done, total); see :data:`dsage_ray.core.runner.ProgressCallback`.
Progress = Callable[[str, int, int], None]


def head_label(head: str, measure_names: Sequence[str]) -> str:
    """``measure_1`` → the measure's name, so metrics read ``mae_mean_path_length``."""
    if head.startswith("measure_"):
        return measure_names[int(head.split("_")[1])]
    return head


class HeldOutLevels:
    """The held-out set of one run and the surrogate's accuracy on it.

    Args:
        count: Levels to hold out.
        domain: Supplies the random valid levels and their measures' names.
        seeds: The run's seed streams (:meth:`~dsage_ray.core.seeds.RunSeeds.holdout_evaluation`).

    Attributes:
        data: ``{"solutions", "results"}`` (successful evaluations only) once evaluated, else None.
        evaluations: Real evaluations spent on them, outside the budget (retries not counted).
    """

    def __init__(self, *, count: int, domain: Domain, seeds: "RunSeeds") -> None:
        self.count = count
        self.domain = domain
        self.seeds = seeds
        self.data: dict[str, Any] | None = None
        self.evaluations = 0
        self._encoded: np.ndarray | None = None

    @property
    def pending(self) -> bool:
        """Levels are to be held out and have not been evaluated yet."""
        return self.count > 0 and self.data is None

    def evaluate(self, evaluator: Evaluator, *, progress: Progress | None = None) -> None:
        """Evaluates the held-out levels for real, once; failed evaluations are left out of the set."""
        # Random *valid* levels: an invalid Maze has path length 0 whatever the agent, which would
        # flatter the surrogate.
        solutions = self.domain.random_valid_solutions(self.count, np.random.default_rng(self.seeds.holdout_levels))
        seeds = [self.seeds.holdout_evaluation(i) for i in range(self.count)]
        if progress is not None:
            progress("holdout", 0, self.count)
        results = evaluate_with_retry(evaluator, solutions, seeds)
        if progress is not None:
            progress("holdout", self.count, self.count)
        ok = [i for i, r in enumerate(results) if not r.failed]
        # The results' info dicts are diagnostics; checkpoints keep only what scoring needs.
        self.data = {
            "solutions": solutions[ok],
            "results": [EvaluationResult(objective=results[i].objective, measures=results[i].measures,
                                         occupancy=results[i].occupancy) for i in ok],
        }
        self.evaluations = self.count
        self._encoded = None

    def score(self, surrogate: "Surrogate") -> dict[str, float]:
        """The surrogate's MAE and Spearman ρ per head on the held-out levels.

        ρ is left out for a head whose true or predicted values are all equal (it is undefined),
        e.g. the Maze validity objective, which is 1 on every valid level.
        """
        if not self.data or not self.data["results"]:
            return {}
        names = self.domain.measure_names
        if self._encoded is None:
            self._encoded = encode_solutions(self.domain, self.data["solutions"])
        prediction = surrogate.predict(self._encoded)
        results = self.data["results"]
        metrics = {f"holdout_mae_{head_label(k, names)}": v
                   for k, v in surrogate.mae(self._encoded, results, prediction=prediction).items()}
        targets = Targets.from_results(results, num_measures=len(names), occupancy_shape=self.domain.occupancy_shape)
        heads = {"objective": (prediction.objective, targets.objective)}
        heads.update({f"measure_{i}": (prediction.measures[:, i], targets.measures[:, i]) for i in range(len(names))})
        for head, (predicted, true) in heads.items():
            if np.ptp(predicted) > 0 and np.ptp(true) > 0:
                metrics[f"holdout_spearman_{head_label(head, names)}"] = float(stats.spearmanr(predicted, true).statistic)
        return metrics

    def state_dict(self) -> dict[str, Any]:
        return {"holdout": self.data, "holdout_evals": self.evaluations}

    def load_state_dict(self, state: dict[str, Any]) -> None:
        # Checkpoints written before held-out levels existed have none.
        self.data = state.get("holdout")
        self.evaluations = state.get("holdout_evals", 0)
        self._encoded = None
