"""The DSAGE outer loop (the paper's Algorithm 1), with every variant selected by config.

One :meth:`DSAGE.step` is one outer iteration: its proposer (:mod:`dsage_ray.core.proposal`) proposes the levels,
they are evaluated for real (:class:`~dsage_ray.core.proposal.Simulation`), the proposer learns from the
results, and the iteration's metrics are recorded. docs/ALGORITHM.md maps each line of Algorithm 1 to the function
that does it. The proposer is chosen by config:

* with a surrogate, DSAGE (:class:`~dsage_ray.core.proposers.SurrogateAssisted`): train the surrogate on the
  dataset (its weights and Adam state persist across iterations), exploit it with a fresh surrogate archive and
  fresh emitters for ``qd.exploit_iterations`` ask → predict → tell iterations, and select picks from the surrogate
  archive. The first iteration evaluates ``n_rand`` random solutions instead;
* without one (``surrogate.kind = "none"``), one ask/evaluate/tell of the QD optimizer on the ground-truth archive
  (:class:`~dsage_ray.core.proposers.DirectQD`): MAP-Elites, CMA-ME or, with the random emitter, domain
  randomisation;
* ``pipeline = true`` wraps DSAGE in :class:`~dsage_ray.core.prefetch.Prefetching` (the next picks are chosen while
  this iteration's are evaluated), and ``search = "auto"`` in :class:`~dsage_ray.core.auto_proposer.AutoSearch`
  (DSAGE until its costs say the domain's direct search does better in the time).

*Held-out accuracy* (``experimental.holdout_levels > 0``): before the first outer iteration, that
many random valid levels are evaluated for real, once. They are extra evaluations, counted as
``holdout_evals`` and never in ``evals``: they use their own seed streams and never enter the
dataset, the archive or the budget, so a run's search is the same with or without them. Every
later iteration scores the freshly trained surrogate on them (``holdout_mae_*``,
``holdout_spearman_*``), next to its error on the batch it selected (``mae_*``). Without a
surrogate nothing is held out (:mod:`dsage_ray.core.holdout`).

*Budgets and cost*: a run ends when ``budget`` evaluations are spent or, with ``time_budget > 0``,
when its wall time reaches ``time_budget`` seconds, whichever comes first. A time budget that runs out
while a batch is being evaluated stops the batch there: the levels under way finish, the rest are
dropped, and the iteration ends with what was evaluated, learned as usual (``evaluated_this_iteration``
says how many). So a run overshoots its time budget by at most one level per simulator, plus the
surrogate's phases if the time ran out during them. Wall time is the time spent inside :meth:`DSAGE.step`, cumulative
across resumes (it is part of the state dict), so a stopped and resumed run counts only the time it ran. Every metric
row carries it (``wall_time``) and the CPU time of this process during the steps (``cpu_time``,
:func:`time.process_time`: every thread of the process that runs the outer loop, so in-process
evaluation is included, the CPU of Ray's simulator actors is not). Where a time budget stops a run
depends on the machine and its load: a time-limited run is not reproducible across machines or runs,
while an evaluation-budget run is (timings are its only numbers that differ).

Nothing here imports Ray: the domain and the evaluator are injected.
"""

from __future__ import annotations

import copy
import time
from typing import Any

import numpy as np

from dsage_ray.config import RunConfig, changed_keys
from dsage_ray.core.auto_proposer import AutoSearch
from dsage_ray.core.evaluation import InProcessEvaluator
from dsage_ray.core.outputs import write_outputs
from dsage_ray.core.prefetch import Prefetching
from dsage_ray.core.proposal import EvaluatedBatch, ProgressCallback, Proposal, Proposer, Simulation
from dsage_ray.core.proposers import DirectQD, SurrogateAssisted, domain_archive
from dsage_ray.core.seeds import RunSeeds
from dsage_ray.core.snapshot import RunSnapshot
from dsage_ray.core.threads import torch_threads
from dsage_ray.domains import build_domain
from dsage_ray.errors import DsageError
from dsage_ray.qd.archives import archive_stats
from dsage_ray.qd.growth import GrowthPoint, growth_curve
from dsage_ray.types import Domain, Evaluator

__all__ = ["DSAGE", "EvaluationsFailed", "ProgressCallback", "torch_threads"]


class EvaluationsFailed(DsageError, RuntimeError):
    """Every real evaluation of an outer iteration failed: the run stops with the evaluations' own error."""


class DSAGE:
    """One DSAGE run (or one of its baselines), advanced an outer iteration at a time.

    Args:
        config: The run's config.
        evaluator: Evaluates solutions for real; defaults to evaluating in this process.
        domain: The domain; defaults to ``build_domain(config)``.
        progress: Optional progress callback.

    Attributes:
        archive: The ground-truth archive: every real evaluation that succeeded, competing per cell.
        proposer: Where the levels come from (:class:`~dsage_ray.core.proposers.SurrogateAssisted`
            with a surrogate, else :class:`~dsage_ray.core.proposers.DirectQD`; wrapped by
            :class:`~dsage_ray.core.prefetch.Prefetching` or :class:`~dsage_ray.core.auto_proposer.AutoSearch`
            where the config asks).
        evals, outer_iteration: Real evaluations spent, outer iterations done.
        wall_time, cpu_time: Seconds spent in :meth:`step` (wall clock) and CPU seconds of this process
            during it, over the whole run including the parts before a resume.
        history: One metrics row per outer iteration.
        failures: The evaluations that failed, with their seed, error and solution.
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
        self.seeds = RunSeeds(seed=config.seed)
        # Created before the proposer: its seed is the first of the QD stream.
        self.archive = domain_archive(self.domain, with_occupancy=True, seed=self.seeds.next_qd_seed())
        self.evals = 0
        self.outer_iteration = 0
        self.wall_time = 0.0
        self.cpu_time = 0.0
        self.history: list[dict[str, float]] = []
        self.failures: list[dict[str, Any]] = []
        #: The archive's numbers within the last outer iteration (for TensorBoard; not part of the run's state).
        self.growth: tuple[GrowthPoint, ...] = ()
        #: When the step under way began (:func:`time.perf_counter`; None: none under way).
        self._step_started: float | None = None
        self.proposer = self._make_proposer()

    def _make_proposer(self) -> Proposer:
        """The proposer the config names: DSAGE or a direct search, DSAGE wrapped for ``pipeline`` or ``auto``."""
        config, domain, archive, seeds = self.config, self.domain, self.archive, self.seeds
        if not config.uses_surrogate:
            return DirectQD(config=config, domain=domain, archive=archive, seeds=seeds)
        dsage = SurrogateAssisted(config=config, domain=domain, archive=archive, seeds=seeds,
                                  evaluator=self.evaluator, progress=self.progress)
        if config.search == "auto":
            return AutoSearch(dsage=dsage, config=config, domain=domain, archive=archive, seeds=seeds, run=self)
        return Prefetching(inner=dsage) if config.pipeline else dsage

    # ------------------------------------------------------------------------------------ loop

    @property
    def done(self) -> bool:
        """The evaluation budget is spent, or the time budget (if any) was reached in the last step."""
        return self.evals >= self.config.budget or self.out_of_time

    @property
    def out_of_time(self) -> bool:
        """``time_budget`` is set and the run's wall time has reached it."""
        return 0 < self.config.time_budget <= self.wall_time

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
        """One outer iteration of Algorithm 1 (docs/ALGORITHM.md): propose → evaluate → learn → record."""
        started = self._step_started = time.perf_counter()
        # Model improvement, exploitation and selection: the levels to evaluate (the first iteration: random ones).
        proposal = self.proposer.propose(outer_iteration=self.outer_iteration)
        # Agent simulation: the levels evaluated for real, within the evaluation and time budgets.
        simulation = self._simulation(proposal)
        tic = time.perf_counter()
        self.proposer.evaluate(simulation)
        simulation.times["evaluate"] = time.perf_counter() - tic
        batch = simulation.batch(domain=self.domain, outer_iteration=self.outer_iteration)
        self._record_failures(batch)
        new_cells = self._count_new_cells(batch.measures)
        # Read before the batch enters the archive; it changes nothing the search computes.
        self.growth = growth_curve(self.archive, measures=batch.measures, objective=batch.objective,
                                   evals_at=[self.evals + i + 1 for i in batch.ok], budget=self.config.budget)
        # The batch enters the ground-truth archive and the dataset.
        metrics = {**proposal.metrics, **self.proposer.learn(batch)}
        self.evals += len(batch.solutions)
        self.outer_iteration += 1
        self._step_started = None
        simulation.times["total"] = time.perf_counter() - started
        return self._record(metrics, batch, new_cells=new_cells, times=simulation.times)

    def _simulation(self, proposal: Proposal) -> Simulation:
        """The agent simulation of ``proposal``: within the evaluation budget, each level with its evaluation's seed."""
        count = len(proposal.solutions[: self.config.budget - self.evals])
        return Simulation(proposal=proposal, evaluator=self.evaluator, evals=self.evals, budget=self.config.budget,
                          seeds=[self.seeds.evaluation(self.evals + i) for i in range(count)],
                          deadline=self.deadline, progress=self.progress, times=proposal.times)

    def _record(self, metrics: dict[str, float], batch: EvaluatedBatch, *, new_cells: int,
                times: dict[str, float]) -> dict[str, float]:
        """The iteration's metrics row (the run's ``wall_time`` and ``cpu_time`` are added by :meth:`step`)."""
        evaluated = len(batch.solutions)
        metrics.update(archive_stats(self.archive))
        metrics.update(
            archive_size=float(len(self.archive)),
            outer_iteration=float(self.outer_iteration),
            evals=float(self.evals),
            evaluated_this_iteration=float(evaluated),
            failed_evals=float(len(self.failures)),
            new_cell_share=float(new_cells) / max(evaluated, 1),
            holdout_evals=float(self.holdout_evals),
        )
        metrics.update({f"time_{k}": v for k, v in times.items()})
        return metrics

    @property
    def deadline(self) -> float | None:
        """The :func:`time.perf_counter` value at which the time budget runs out (None: no time budget)."""
        if self.config.time_budget <= 0:
            return None
        started = self._step_started if self._step_started is not None else time.perf_counter()
        return started + self.config.time_budget - self.wall_time

    def time_left(self) -> float | None:
        """Seconds of the time budget left now, the step under way counted (None: no time budget)."""
        deadline = self.deadline
        return None if deadline is None else deadline - time.perf_counter()

    def _record_failures(self, batch: EvaluatedBatch) -> None:
        """Keeps each failed evaluation (after its retry); stops the run where every one failed."""
        for i, result in enumerate(batch.results):
            if result.failed:
                self.failures.append({"eval_index": self.evals + i, "seed": batch.seeds[i], "error": result.error,
                                      "solution": np.asarray(batch.solutions[i]).tolist()})
        if batch.results and not batch.ok:
            # Nothing was learned and nothing would be: a broken agent or simulator fails every batch.
            raise EvaluationsFailed(f"every evaluation of outer iteration {self.outer_iteration} failed "
                                    f"({len(batch.results)} of {len(batch.results)}, after retries); the first: "
                                    f"{batch.results[0].error}")

    def _count_new_cells(self, measures: np.ndarray) -> int:
        """How many of these results land in a ground-truth cell that was empty before the batch."""
        if len(measures) == 0:
            return 0
        occupied, _ = self.archive.retrieve(measures)
        return int(np.sum(~occupied))

    # --------------------------------------------------------------------------------- reading

    @property
    def surrogate(self):
        """The surrogate model, or None for a direct QD run."""
        return getattr(self.proposer, "surrogate", None)

    @property
    def dataset(self):
        """The surrogate's dataset of real evaluations, or None for a direct QD run."""
        return getattr(self.proposer, "dataset", None)

    @property
    def holdout(self) -> dict[str, Any] | None:
        """The held-out levels and their real results (successful ones only), once evaluated."""
        held = getattr(self.proposer, "holdout", None)
        return None if held is None else held.data

    @property
    def holdout_evals(self) -> int:
        """Real evaluations spent on held-out levels, outside the budget (retries not counted)."""
        held = getattr(self.proposer, "holdout", None)
        return 0 if held is None else held.evaluations

    @property
    def last_predictions(self) -> tuple[np.ndarray, np.ndarray] | None:
        """``(predicted_measures, true_measures)`` for the batch a surrogate predicted last (Fig. 9 scatter)."""
        return getattr(self.proposer, "last_predictions", None)

    def snapshot(self) -> RunSnapshot:
        """What outputs and callbacks read after an outer iteration (:class:`~dsage_ray.core.snapshot.RunSnapshot`)."""
        return RunSnapshot(config=self.config, domain=self.domain, archive=self.archive, history=tuple(self.history),
                           failures=tuple(self.failures), evals=self.evals, outer_iteration=self.outer_iteration,
                           wall_time=self.wall_time, done=self.done, last_predictions=self.last_predictions,
                           growth=self.growth)

    def write_outputs(self, run_dir) -> None:
        """Writes metrics.json, archive.csv, heatmap.png and a few elites into ``run_dir``."""
        write_outputs(self.snapshot(), run_dir)

    # ---------------------------------------------------------------------------------- state

    def state_dict(self) -> dict[str, Any]:
        """Everything needed to continue this run exactly: picklable, no live handles."""
        # One deepcopy of the whole dict, so that objects shared between parts (a QD scheduler holds the
        # archive) stay shared in the copy.
        return copy.deepcopy({
            "config": self.config.to_dict(),
            "evals": self.evals,
            "outer_iteration": self.outer_iteration,
            "wall_time": self.wall_time,
            "cpu_time": self.cpu_time,
            "history": self.history,
            "failures": self.failures,
            **self.seeds.state_dict(),
            "archive": self.archive,
            **self.proposer.state_dict(),
            "last_predictions": self.last_predictions,
        })

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Continues from ``state``; its config must be this run's, but for ``time_budget``.

        The time budget only decides when the run stops, never what it computes, so a resume may raise
        it (or lower it) to continue a run its time budget ended.
        """
        saved = RunConfig.build(state["config"]).replace(time_budget=self.config.time_budget)
        changes = changed_keys(saved, self.config)
        if changes:
            raise ValueError(f"checkpoint was written by a run with a different config: {'; '.join(changes)}")
        state = copy.deepcopy(state)
        self.evals = state["evals"]
        self.outer_iteration = state["outer_iteration"]
        # Checkpoints written before timings were saved start the count at the resume.
        self.wall_time = state.get("wall_time", 0.0)
        self.cpu_time = state.get("cpu_time", 0.0)
        self.history = state["history"]
        self.failures = state["failures"]
        self.archive = state["archive"]
        # Before the seeds load: a direct search that took over (search = "auto") is built again, and its
        # construction may draw from streams the stored ones already account for.
        self.proposer.load_state_dict(state)
        self.seeds.load_state_dict(state)
