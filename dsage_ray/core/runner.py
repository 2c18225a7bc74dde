"""The DSAGE outer loop (the paper's Algorithm 1), with every variant selected by config.

One :meth:`DSAGE.step` is one outer iteration:

1. *Model improvement*: train the surrogate on the most recent evaluations (its weights and Adam
   state persist across iterations).
2. *Model exploitation*: a fresh surrogate archive and fresh emitters run ``qd.exploit_iterations``
   ask → predict → tell iterations against the surrogate.
3. *Selection*: downsample / random / full picks from the surrogate archive.
4. *Agent simulation*: the picks are evaluated for real and enter the ground-truth archive and the
   dataset.

The first iteration evaluates ``n_rand`` random solutions instead. With
``selection.skip_filled`` (the ``dsage_novel`` variant, not the paper's) step 3 drops the picks
the ground-truth archive already beats, by the surrogate's prediction.

*Held-out accuracy* (``surrogate.holdout_levels > 0``): before the first outer iteration, that
many random valid levels are evaluated for real, once. They are extra evaluations, counted as
``holdout_evals`` and never in ``evals``: they use their own seed streams and never enter the
dataset, the archive or the budget, so a run's search is the same with or without them. Every
later iteration scores the freshly trained surrogate on them (``holdout_mae_*``,
``holdout_spearman_*``), next to its error on the batch it selected (``mae_*``). Without a
surrogate nothing is held out. Without a surrogate
(``surrogate.kind = "none"``) a step is one ask/evaluate/tell of the QD optimizer on the
ground-truth archive: MAP-Elites, CMA-ME or, with the random emitter, domain randomisation.

*Budgets and cost*: a run ends when ``budget`` evaluations are spent or, with ``time_budget > 0``,
after the outer iteration during which its wall time reached ``time_budget`` seconds, whichever
comes first. Wall time is the time spent inside :meth:`DSAGE.step`, cumulative across resumes (it is
part of the state dict), so a stopped and resumed run counts only the time it ran. Every metric row
carries it (``wall_time``) and the CPU time of this process during the steps (``cpu_time``,
:func:`time.process_time`: every thread of the process that runs the outer loop, so in-process
evaluation is included, the CPU of Ray's simulator actors is not). Where a time budget stops a run
depends on the machine and its load: a time-limited run is not reproducible across machines or runs,
while an evaluation-budget run is (timings are its only numbers that differ).

Nothing here imports Ray: the domain and the evaluator are injected.
"""

from __future__ import annotations

import contextlib
import copy
import time
from typing import Any, Callable, Iterator

import numpy as np
from scipy import stats

from dsage_ray.config import RunConfig
from dsage_ray.core.evaluation import InProcessEvaluator, evaluate_with_retry
from dsage_ray.core.outputs import write_outputs
from dsage_ray.domains import build_domain
from dsage_ray.errors import DsageError
from dsage_ray.qd.archives import archive_stats, make_archive
from dsage_ray.qd.optimizer import make_scheduler, run_inner_loop
from dsage_ray.qd.selection import gather_elites, select_solutions, skip_filled
from dsage_ray.surrogate.dataset import Targets
from dsage_ray.surrogate.models import pad_to_power_of_two
from dsage_ray.types import Domain, EvaluationResult, Evaluator, Solutions

class EvaluationsFailed(DsageError, RuntimeError):
    """Every real evaluation of an outer iteration failed: the run stops with the evaluations' own error."""


#: Called with (phase, done, total) while a step runs; the CLI turns it into progress bars.
ProgressCallback = Callable[[str, int, int], None]


class DSAGE:
    """One DSAGE run (or one of its baselines), advanced an outer iteration at a time.

    Args:
        config: The run's config.
        evaluator: Evaluates solutions for real; defaults to evaluating in this process.
        domain: The domain; defaults to ``build_domain(config)``.
        progress: Optional progress callback.
    """

    def __init__(
        self,
        *,
        config: RunConfig,
        evaluator: Evaluator | None = None,
        domain: Domain | None = None,
        progress: ProgressCallback | None = None,
    ) -> None:
        config.validate()
        self.config = config
        self.domain = domain if domain is not None else build_domain(config)
        self.evaluator = evaluator if evaluator is not None else InProcessEvaluator(domain=self.domain)
        self.progress = progress
        self._seeds = np.random.SeedSequence(config.seed)
        # Independent streams so that, e.g., a different inner-loop length never shifts the
        # evaluation seeds.
        streams = self._seeds.spawn(3)
        self.rng = np.random.default_rng(streams[0])
        self._eval_seed_root = int(streams[1].generate_state(1)[0])
        self._qd_seed_root = streams[2]
        # Spawned after the three above, which therefore do not depend on whether levels are held out.
        holdout_levels_seed, holdout_evals_seed = self._seeds.spawn(1)[0].spawn(2)
        self._holdout_levels_seed = holdout_levels_seed
        self._holdout_eval_seed_root = int(holdout_evals_seed.generate_state(1)[0])

        self.archive = self._make_archive(with_occupancy=True, seed=self._next_qd_seed())
        self.evals = 0
        self.outer_iteration = 0
        #: Seconds spent in :meth:`step` (wall clock) and CPU seconds of this process during it, over the
        #: whole run including the parts before a resume.
        self.wall_time = 0.0
        self.cpu_time = 0.0
        self.history: list[dict[str, float]] = []
        self.failures: list[dict[str, Any]] = []
        #: ``(predicted_measures, true_measures)`` for the batch evaluated last (Fig. 9 scatter).
        self.last_predictions: tuple[np.ndarray, np.ndarray] | None = None
        #: Held-out levels and their real results (successful ones only), once evaluated.
        self.holdout: dict[str, Any] | None = None
        #: Real evaluations spent on held-out levels, outside the budget (retries not counted).
        self.holdout_evals = 0
        self._holdout_encoded: np.ndarray | None = None

        self.surrogate = None
        self.dataset = None
        self.scheduler = None
        if config.uses_surrogate:
            from dsage_ray.surrogate import Surrogate

            sample = self._encode(self.domain.random_solutions(1, np.random.default_rng(0)))
            self.surrogate = Surrogate(
                kind=config.surrogate.kind,
                input_channels=sample.shape[1],
                input_shape=tuple(sample.shape[2:]),
                occupancy_shape=self.domain.occupancy_shape,
                num_measures=len(self.domain.measure_names),
                config=config.surrogate,
                seed=int(self._next_qd_seed()),
                measure_ranges=self.domain.measure_ranges,
                measure_names=self.domain.measure_names,
            )
            self.dataset = self.surrogate.make_dataset()
        else:
            self.scheduler = make_scheduler(
                self.archive,
                config=config.qd,
                solution_dim=self.domain.solution_dim,
                random_solutions=self.domain.random_solutions,
                seed=self._next_qd_seed(),
            )

    # ------------------------------------------------------------------------------------ loop

    @property
    def done(self) -> bool:
        """The evaluation budget is spent, or the time budget (if any) was reached in the last step."""
        return self.evals >= self.config.budget or self.out_of_time

    @property
    def out_of_time(self) -> bool:
        """``time_budget`` is set and the run's wall time has reached it."""
        return 0 < self.config.time_budget <= self.wall_time

    @property
    def ground_truth_archive(self):
        return self.archive

    def run(self) -> list[dict[str, float]]:
        """Steps until the evaluation or time budget is spent; returns the per-iteration metrics."""
        while not self.done:
            self.step()
        return self.history

    def step(self) -> dict[str, float]:
        """Runs one outer iteration and returns its metrics.

        Torch runs on ``config.torch_threads`` threads during the step, whoever calls it (the
        caller's setting is restored afterwards): the surrogate's numbers depend on the count.
        The step's wall and CPU time are added to the run's (``wall_time``, ``cpu_time`` in the metrics).
        """
        if self.out_of_time:
            raise RuntimeError(f"the time budget ({self.config.time_budget:g} s) is spent")
        if self.done:
            raise RuntimeError(f"the evaluation budget ({self.config.budget}) is spent")
        wall, cpu = time.perf_counter(), time.process_time()
        with torch_threads(self.config.torch_threads):
            metrics = self._step()
        self.wall_time += time.perf_counter() - wall
        self.cpu_time += time.process_time() - cpu
        metrics.update(wall_time=self.wall_time, cpu_time=self.cpu_time)
        self.history.append(metrics)
        return metrics

    def _step(self) -> dict[str, float]:
        times: dict[str, float] = {}
        metrics: dict[str, float] = {}
        started = time.perf_counter()

        if self.scheduler is not None:
            solutions = self.scheduler.ask()
        elif self.outer_iteration == 0:
            if self.config.surrogate.holdout_levels and self.holdout is None:
                tic = time.perf_counter()
                self._evaluate_holdout()
                times["holdout"] = time.perf_counter() - tic
            solutions = self.domain.random_solutions(self.config.n_rand, self.rng)
        else:
            tic = time.perf_counter()
            losses = self.surrogate.train(self.dataset)
            metrics["surrogate_loss"] = losses.pop("total")
            metrics["surrogate_epochs"] = losses.pop("epochs")
            if "validation" in losses:
                metrics["surrogate_validation_loss"] = losses.pop("validation")
            metrics.update({f"surrogate_loss_{self._head_name(k)}": v for k, v in losses.items()})
            times["train"] = time.perf_counter() - tic
            if self.holdout is not None:
                tic = time.perf_counter()
                metrics.update(self._holdout_accuracy())
                times["holdout"] = time.perf_counter() - tic
            tic = time.perf_counter()
            surrogate_archive = self._exploit()
            times["exploit"] = time.perf_counter() - tic
            tic = time.perf_counter()
            picks = select_solutions(
                surrogate_archive,
                method=self.config.selection.method,
                block=self.config.selection.block,
                count=self.config.selection.count,
                rng=self.rng,
            )
            if self.config.selection.skip_filled:
                skipped = skip_filled(surrogate_archive, picks, self.archive)
                picks = skipped.kept
                metrics["selection_filled"] = float(skipped.filled)
                metrics["selection_fallback"] = float(skipped.fallback)
            solutions = gather_elites(surrogate_archive, picks)["solution"]
            times["select"] = time.perf_counter() - tic
            metrics["surrogate_archive_size"] = float(len(surrogate_archive))

        full_batch = len(solutions)
        solutions = solutions[: self.config.budget - self.evals]
        predicted = None
        encoded = self._encode(solutions) if self.surrogate is not None else None
        if self.surrogate is not None and self.outer_iteration > 0 and len(solutions):
            predicted = self.surrogate.predict(encoded)

        tic = time.perf_counter()
        results = self._evaluate(solutions)
        times["evaluate"] = time.perf_counter() - tic

        ok = [i for i, r in enumerate(results) if not r.failed]
        if results and not ok:
            # Nothing was learned and nothing would be: a broken agent or simulator fails every batch.
            raise EvaluationsFailed(f"every evaluation of outer iteration {self.outer_iteration} failed "
                                    f"({len(results)} of {len(results)}, after retries); the first: {results[0].error}")
        objective = np.array([results[i].objective for i in ok], dtype=np.float64)
        measures = np.array([results[i].measures for i in ok], dtype=np.float64).reshape(len(ok), len(self.domain.measure_names))
        occupancy = np.array([results[i].occupancy for i in ok], dtype=np.float32).reshape(
            (len(ok),) + tuple(self.domain.occupancy_shape)
        )
        new_cells = self._count_new_cells(measures)
        if self.scheduler is not None and len(ok) == full_batch:
            # The emitters need the whole batch they asked for; tell() also adds to the archive.
            self.scheduler.tell(objective, measures, occupancy=occupancy)
        else:
            if len(ok):
                self.archive.add(solutions[ok], objective, measures, occupancy=occupancy)
            if self.scheduler is not None:
                # A batch with failed (or budget-truncated) evaluations cannot be told: pyribs needs
                # the whole batch it asked for. A fresh scheduler over the same archive and emitters
                # closes the ask/tell cycle; the emitters simply never learn from this one batch.
                from ribs.schedulers import Scheduler

                self.scheduler = Scheduler(self.archive, self.scheduler.emitters)
        if self.dataset is not None and len(ok):
            self.dataset.append(encoded=encoded, results=results)
        if predicted is not None and len(ok):
            errors = self.surrogate.mae(encoded, results, prediction=predicted)
            metrics.update({f"mae_{self._head_name(k)}": v for k, v in errors.items()})
            self.last_predictions = (predicted.measures[ok], measures)

        self.evals += len(solutions)
        self.outer_iteration += 1
        times["total"] = time.perf_counter() - started
        metrics.update(archive_stats(self.archive))
        metrics.update(
            archive_size=float(len(self.archive)),
            outer_iteration=float(self.outer_iteration),
            evals=float(self.evals),
            evaluated_this_iteration=float(len(solutions)),
            failed_evals=float(len(self.failures)),
            new_cell_share=float(new_cells) / max(len(solutions), 1),
            holdout_evals=float(self.holdout_evals),
        )
        metrics.update({f"time_{k}": v for k, v in times.items()})
        return metrics

    # -------------------------------------------------------------------------------- phases

    def _exploit(self):
        archive = self._make_archive(with_occupancy=False, seed=self._next_qd_seed())
        scheduler = make_scheduler(
            archive,
            config=self.config.qd,
            solution_dim=self.domain.solution_dim,
            random_solutions=self.domain.random_solutions,
            seed=self._next_qd_seed(),
        )

        def predict(solutions: Solutions):
            prediction = self.surrogate.predict(self._encode(solutions))
            return prediction.objective, prediction.measures, {}

        progress = None
        if self.progress is not None:
            total = self.config.qd.exploit_iterations
            done = iter(range(1, total + 1))
            # run_inner_loop reports one increment per iteration; our callback takes a running count.
            progress = lambda _increment: self.progress("exploit", next(done), total)  # noqa: E731
        run_inner_loop(scheduler, predict, self.config.qd.exploit_iterations, progress=progress)
        return archive

    def _evaluate_holdout(self) -> None:
        """Evaluates the held-out levels for real, once; failed evaluations are left out of the set."""
        count = self.config.surrogate.holdout_levels
        # Random *valid* levels: an invalid Maze has path length 0 whatever the agent, which would
        # flatter the surrogate.
        solutions = self.domain.random_valid_solutions(count, np.random.default_rng(self._holdout_levels_seed))
        seeds = [int(np.random.SeedSequence([self._holdout_eval_seed_root, i]).generate_state(1)[0])
                 for i in range(count)]
        if self.progress is not None:
            self.progress("holdout", 0, count)
        results = evaluate_with_retry(self.evaluator, solutions, seeds)
        if self.progress is not None:
            self.progress("holdout", count, count)
        ok = [i for i, r in enumerate(results) if not r.failed]
        # The results' info dicts are diagnostics; checkpoints keep only what scoring needs.
        self.holdout = {
            "solutions": solutions[ok],
            "results": [EvaluationResult(objective=results[i].objective, measures=results[i].measures,
                                         occupancy=results[i].occupancy) for i in ok],
        }
        self.holdout_evals = count
        self._holdout_encoded = None

    def _holdout_accuracy(self) -> dict[str, float]:
        """The surrogate's MAE and Spearman ρ per head on the held-out levels.

        ρ is left out for a head whose true or predicted values are all equal (it is undefined),
        e.g. the Maze validity objective, which is 1 on every valid level.
        """
        if not self.holdout["results"]:
            return {}
        if self._holdout_encoded is None:
            self._holdout_encoded = self._encode(self.holdout["solutions"])
        prediction = self.surrogate.predict(self._holdout_encoded)
        results = self.holdout["results"]
        metrics = {f"holdout_mae_{self._head_name(k)}": v
                   for k, v in self.surrogate.mae(self._holdout_encoded, results, prediction=prediction).items()}
        targets = Targets.from_results(results, num_measures=len(self.domain.measure_names),
                                       occupancy_shape=self.domain.occupancy_shape)
        heads = {"objective": (prediction.objective, targets.objective)}
        heads.update({f"measure_{i}": (prediction.measures[:, i], targets.measures[:, i])
                      for i in range(len(self.domain.measure_names))})
        for head, (predicted, true) in heads.items():
            if np.ptp(predicted) > 0 and np.ptp(true) > 0:
                rho = stats.spearmanr(predicted, true).statistic
                metrics[f"holdout_spearman_{self._head_name(head)}"] = float(rho)
        return metrics

    def _head_name(self, head: str) -> str:
        """``measure_1`` → the measure's name, so metrics read ``mae_mean_path_length``."""
        if head.startswith("measure_"):
            return self.domain.measure_names[int(head.split("_")[1])]
        return head

    def _encode(self, solutions: Solutions) -> np.ndarray:
        """The surrogate's input: the domain's one-hot levels, padded to a square power of two."""
        return pad_to_power_of_two(self.domain.encode(solutions), pad_channel=self.domain.encoding_pad_channel)

    def _count_new_cells(self, measures: np.ndarray) -> int:
        """How many of these results land in a ground-truth cell that was empty before the batch."""
        if len(measures) == 0:
            return 0
        occupied, _ = self.archive.retrieve(measures)
        return int(np.sum(~occupied))

    def _evaluate(self, solutions: Solutions) -> list[EvaluationResult]:
        seeds = [self._eval_seed(self.evals + i) for i in range(len(solutions))]
        results = evaluate_with_retry(self.evaluator, solutions, seeds)
        for i, result in enumerate(results):
            if result.failed:
                self.failures.append({"eval_index": self.evals + i, "seed": seeds[i], "error": result.error,
                                      "solution": np.asarray(solutions[i]).tolist()})
        if self.progress is not None:
            self.progress("evaluate", self.evals + len(solutions), self.config.budget)
        return results

    def _eval_seed(self, eval_index: int) -> int:
        """Evaluation ``i``'s seed depends only on the run seed and ``i``, never on who evaluates it."""
        return int(np.random.SeedSequence([self._eval_seed_root, eval_index]).generate_state(1)[0])

    def _next_qd_seed(self) -> int:
        return int(self._qd_seed_root.spawn(1)[0].generate_state(1)[0])

    def _make_archive(self, *, with_occupancy: bool, seed: int):
        return make_archive(
            solution_dim=self.domain.solution_dim,
            dims=self.domain.archive_dims,
            ranges=self.domain.measure_ranges,
            occupancy_shape=self.domain.occupancy_shape if with_occupancy else None,
            seed=seed,
            solution_dtype=self.domain.solution_dtype,
        )

    def write_outputs(self, run_dir) -> None:
        """Writes metrics.json, archive.csv, heatmap.png and a few elites into ``run_dir``."""
        write_outputs(self, run_dir)

    # ---------------------------------------------------------------------------------- state

    def state_dict(self) -> dict[str, Any]:
        """Everything needed to continue this run exactly: picklable, no live handles."""
        return copy.deepcopy({
            "config": self.config.to_dict(),
            "evals": self.evals,
            "outer_iteration": self.outer_iteration,
            "wall_time": self.wall_time,
            "cpu_time": self.cpu_time,
            "history": self.history,
            "failures": self.failures,
            "rng": self.rng.bit_generator.state,
            "qd_seed_root": self._qd_seed_root,
            "archive": self.archive,
            "scheduler": self.scheduler,
            "surrogate": None if self.surrogate is None else self.surrogate.state_dict(),
            "dataset": None if self.dataset is None else self.dataset.state_dict(),
            "last_predictions": self.last_predictions,
            "holdout": self.holdout,
            "holdout_evals": self.holdout_evals,
        })

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Continues from ``state``; its config must be this run's, but for ``time_budget``.

        The time budget only decides when the run stops, never what it computes, so a resume may raise
        it (or lower it) to continue a run its time budget ended.
        """
        saved = RunConfig.build(state["config"]).replace(time_budget=self.config.time_budget)
        if saved.to_dict() != self.config.to_dict():
            raise ValueError("checkpoint was written by a run with a different config")
        state = copy.deepcopy(state)
        self.evals = state["evals"]
        self.outer_iteration = state["outer_iteration"]
        # Checkpoints written before timings were saved start the count at the resume.
        self.wall_time = state.get("wall_time", 0.0)
        self.cpu_time = state.get("cpu_time", 0.0)
        self.history = state["history"]
        self.failures = state["failures"]
        self.rng.bit_generator.state = state["rng"]
        self._qd_seed_root = state["qd_seed_root"]
        self.archive = state["archive"]
        self.scheduler = state["scheduler"]
        if self.surrogate is not None:
            self.surrogate.load_state_dict(state["surrogate"])
            self.dataset.load_state_dict(state["dataset"])
        self.last_predictions = state["last_predictions"]
        # Checkpoints written before held-out levels existed have none.
        self.holdout = state.get("holdout")
        self.holdout_evals = state.get("holdout_evals", 0)
        self._holdout_encoded = None


@contextlib.contextmanager
def torch_threads(count: int) -> Iterator[None]:
    """Runs the block with ``count`` torch intra-op threads, then restores the caller's count.

    The count a run trains and predicts with is part of its config, so ``--local``, a Tune trial
    and a resumed run compute the same floats whatever their process was set to.
    """
    import torch

    previous = torch.get_num_threads()
    torch.set_num_threads(count)
    try:
        yield
    finally:
        torch.set_num_threads(previous)
