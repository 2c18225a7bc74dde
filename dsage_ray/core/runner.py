"""The DSAGE outer loop (the paper's Algorithm 1), with every variant selected by config.

One :meth:`DSAGE.step` is one outer iteration. Its proposer (:mod:`dsage_ray.core.proposers`) proposes
the levels; they are evaluated for real; the proposer learns from the results. With a surrogate
(:class:`~dsage_ray.core.proposers.SurrogateAssisted`), that is:

1. *Model improvement*: train the surrogate on the most recent evaluations (its weights and Adam
   state persist across iterations).
2. *Model exploitation*: a fresh surrogate archive and fresh emitters run ``qd.exploit_iterations``
   ask → predict → tell iterations against the surrogate.
3. *Selection*: downsample / random / full picks from the surrogate archive.
4. *Agent simulation*: the picks are evaluated for real and enter the ground-truth archive and the
   dataset.

The first iteration evaluates ``n_rand`` random solutions instead.

*Held-out accuracy* (``experimental.holdout_levels > 0``): before the first outer iteration, that
many random valid levels are evaluated for real, once. They are extra evaluations, counted as
``holdout_evals`` and never in ``evals``: they use their own seed streams and never enter the
dataset, the archive or the budget, so a run's search is the same with or without them. Every
later iteration scores the freshly trained surrogate on them (``holdout_mae_*``,
``holdout_spearman_*``), next to its error on the batch it selected (``mae_*``). Without a
surrogate nothing is held out (:mod:`dsage_ray.core.holdout`). Without a surrogate
(``surrogate.kind = "none"``) a step is one ask/evaluate/tell of the QD optimizer on the
ground-truth archive (:class:`~dsage_ray.core.proposers.DirectQD`): MAP-Elites, CMA-ME or, with the
random emitter, domain randomisation.

*Pipelined* (``pipeline = true``, DSAGE only): steps 1–3 of iteration k+1 run while iteration k's picks
are evaluated, so the surrogate that picks them has trained on the evaluations up to iteration k−1 only.
With simulators in other processes (an evaluator with ``runs_elsewhere``, such as the Ray pool) the
batch is submitted first and the driver trains and exploits while it runs; in one process the two run
one after the other. The data each phase sees is the same either way, so a seed gives the same run
in both, and a checkpoint holds the next iteration's picks (:attr:`DSAGE.pending`). The first
iteration cannot overlap: nothing is known until its random batch is back. A step's ``time_*``
entries are the phases that ran during it, so a pipelined step's ``time_train`` is the next picks'
training; ``time_overlapped`` is how long the driver worked while the batch was being evaluated.

*Search auto* (``search = "auto"``): with a time budget, the random iteration is evaluated in parts, and the rest
dropped once it would leave too little time for the surrogate (:meth:`DSAGE._time_random_levels`); right after
the random iteration, the surrogate's first proposal is projected and the direct search takes over at once where
too few surrogate iterations fit in the time left (:meth:`DSAGE._look_at_time_left`); otherwise the first surrogate
iteration's picks are probed before the rest are evaluated (:meth:`DSAGE._probe_first_picks`); where a pick costs
more than the break-even, the rest are dropped and the domain's direct search takes over the same archive
(:mod:`dsage_ray.core.auto_search`).

*Budgets and cost*: a run ends when ``budget`` evaluations are spent or, with ``time_budget > 0``,
when its wall time reaches ``time_budget`` seconds, whichever comes first. A time budget that runs out
while a batch is being evaluated stops the batch there: the levels under way finish, the rest are
dropped, and the iteration ends with what was evaluated, learned as usual (``evaluated_this_iteration``
says how many). So a run overshoots its time budget by at most one level per simulator, plus the
surrogate's phases if the time ran out during them. Wall time is the time spent inside :meth:`DSAGE.step`, cumulative across resumes (it is
part of the state dict), so a stopped and resumed run counts only the time it ran. Every metric row
carries it (``wall_time``) and the CPU time of this process during the steps (``cpu_time``,
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
from dsage_ray.core.auto_search import (PROBE_PICKS, RANDOM_LEVELS_TIMED, SURROGATE_PHASES, SearchChoice,
                                        choose_by_time_left, choose_during_random, choose_search, direct_config,
                                        direct_variant, probe_allowance, random_level_seconds)
from dsage_ray.core.evaluation import InProcessEvaluator, PendingEvaluation
from dsage_ray.core.outputs import write_outputs
from dsage_ray.core.proposers import (DirectQD, EvaluatedBatch, ProgressCallback, Proposal, Proposer,
                                      SurrogateAssisted, domain_archive)
from dsage_ray.core.seeds import RunSeeds
from dsage_ray.core.snapshot import RunSnapshot
from dsage_ray.core.tensorboard_log import GrowthPoint, growth_curve
from dsage_ray.core.threads import torch_threads
from dsage_ray.domains import build_domain
from dsage_ray.errors import DsageError
from dsage_ray.qd.archives import archive_stats
from dsage_ray.types import Domain, EvaluationResult, Evaluator, Solutions

__all__ = ["DSAGE", "EvaluationsFailed", "ProgressCallback", "torch_threads"]


def _surrogate_seconds(proposal: Proposal) -> float:
    """Seconds a surrogate proposal spent training, exploiting and selecting."""
    return sum(proposal.times.get(phase, 0.0) for phase in SURROGATE_PHASES)


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
            with a surrogate, else :class:`~dsage_ray.core.proposers.DirectQD`).
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
        #: A pipelined run's next proposal, chosen while the last batch was evaluated.
        self.pending: Proposal | None = None
        #: The archive's numbers within the last outer iteration (for TensorBoard; not part of the run's state).
        self.growth: tuple[GrowthPoint, ...] = ()
        #: What ``search = "auto"`` chose, once it has (None: not yet, or a fixed search).
        self.search_choice: SearchChoice | None = None
        self.proposer: Proposer
        if config.uses_surrogate:
            self.proposer = SurrogateAssisted(config=config, domain=self.domain, archive=self.archive, seeds=self.seeds,
                                              evaluator=self.evaluator, progress=progress)
        else:
            self.proposer = DirectQD(config=config, domain=self.domain, archive=self.archive, seeds=self.seeds)

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

    def _probe_first_picks(self, proposal: Proposal, solutions: Solutions, seeds: list[int], started: float,
                           look: SearchChoice | None) -> tuple[Proposal, list[EvaluationResult], list[int]]:
        """``search = "auto"``: evaluates :data:`PROBE_PICKS` of the surrogate's first picks, spread over its order
        (the picks come in archive order, where a region of cheap levels may come first), chooses, then evaluates
        the rest or drops it. ``look`` is this step's look at the time left, which kept DSAGE (None: no time budget).
        Returns the proposal of what was evaluated, its results and seeds, in the picks' order: with every pick
        evaluated, the fixed run's batch exactly."""
        tic, count = time.perf_counter(), len(solutions)
        probe = sorted({int(i) for i in np.linspace(0, count - 1, min(PROBE_PICKS, count)).round()})
        # The probe stops once its picks alone have cost more than the break-even allows (Mario's A* may play a
        # pick for half a minute): the choice is then made already.
        allowance = probe_allowance(self.history, surrogate_seconds=_surrogate_seconds(proposal), picks=count,
                                    probed=len(probe))
        deadline = self._deadline(started)
        deadline = tic + allowance if deadline is None else min(deadline, tic + allowance)
        results = dict(zip(probe, PendingEvaluation(
            self.evaluator, solutions[probe], [seeds[i] for i in probe], deadline=deadline,
            progress=self._evaluation_progress()).result()))
        self.search_choice = choose_search(
            self.history, surrogate_seconds=_surrogate_seconds(proposal), picks=count,
            probe_seconds=time.perf_counter() - tic, probed=len(results), direct_variant=direct_variant(self.config),
            before=look)
        proposal.metrics.update(self.search_choice.metrics())
        rest = [i for i in range(count) if i not in results]
        if not self.search_choice.direct and len(results) == len(probe) and rest:
            results.update(zip(rest, PendingEvaluation(
                self.evaluator, solutions[rest], [seeds[i] for i in rest], deadline=self._deadline(started),
                progress=self._evaluation_progress(offset=len(probe))).result()))
        evaluated = sorted(results)
        if len(evaluated) < len(proposal.solutions):
            proposal = proposal.take(evaluated)
        return proposal, [results[i] for i in evaluated], [seeds[i] for i in evaluated]

    def _surrogate_picks(self, evals: int) -> int:
        """Levels a surrogate iteration evaluates after ``evals`` evaluations, within the budget, counted before the
        surrogate has picked any, so a heuristic: ``selection.count``, capped for downsampling (which picks one elite
        per occupied block of the surrogate archive and does not read ``count``) at the archive's blocks. The Mario
        and Maze presets' count of 100 is under their blocks (600, 6,912) and is what their measured looks counted;
        a gym archive of 20 × 20 cells in blocks of 4 × 4 has 25. Before any screen: a screen that drops some makes
        the iteration cheaper than counted here."""
        selection = self.config.selection
        picks = selection.count
        if selection.method == "downsample":
            picks = min(picks, int(np.prod([-(-int(d) // b) for d, b in zip(self.archive.dims, selection.block)])))
        elif selection.method == "full":
            picks = int(np.prod(self.archive.dims))
        return min(picks + selection.elite_mutants, self.config.budget - evals)

    def _time_random_levels(self, proposal: Proposal, solutions: Solutions, seeds: list[int], started: float
                            ) -> tuple[SearchChoice | None, Proposal, list[EvaluationResult], list[int]]:
        """``search = "auto"`` with a time budget, in the random first iteration: evaluates it in parts of
        :data:`~dsage_ray.core.auto_search.RANDOM_LEVELS_TIMED` levels (or one per simulator, if more) and looks after
        each: where the rest, at the seconds of the levels so far, would leave too little time for the surrogate
        (:func:`~dsage_ray.core.auto_search.choose_during_random`), the rest is dropped. Level times are heavy-tailed
        (Mario's A* plays most random levels in a second, a few in half a minute), so one look after the first few
        can miss a slow iteration. Returns the choice (None: none of the looks chose the direct search) and what was
        evaluated, a prefix of the batch: with every level evaluated, the batch exactly as one evaluation gives it."""
        config, count = self.config, len(solutions)
        part = max(RANDOM_LEVELS_TIMED, int(getattr(self.evaluator, "num_workers", 1)))
        tic, results, choice = time.perf_counter(), [], None
        while len(results) < count:
            first, stop = len(results), min(len(results) + part, count)
            got = PendingEvaluation(self.evaluator, solutions[first:stop], seeds[first:stop],
                                    deadline=self._deadline(started),
                                    progress=self._evaluation_progress(offset=first)).result()
            results += got
            if len(got) < stop - first or len(results) == count:  # the time budget stopped it, or it is done
                break
            choice = choose_during_random(seconds=time.perf_counter() - tic, timed=len(results), random_levels=count,
                                          time_left=self._deadline(started) - time.perf_counter(),
                                          picks=self._surrogate_picks(self.evals + count),
                                          evals_left=config.budget - self.evals - count,
                                          direct_variant=direct_variant(config))
            if choice.direct:
                break
        evaluated = len(results)
        if evaluated < len(proposal.solutions):
            proposal = proposal.take(slice(0, evaluated))
        return (choice if choice is not None and choice.direct else None), proposal, results, seeds[:evaluated]

    def _look_at_time_left(self, step_started: float) -> SearchChoice:
        """``search = "auto"`` with a time budget, before the first surrogate proposal: continues with the direct
        search at once where fewer than :data:`~dsage_ray.core.auto_search.MIN_SURROGATE_ITERATIONS` surrogate
        iterations, at their cheapest, fit in the time left. Returns the look (``direct``: it chose so)."""
        config = self.config
        look = choose_by_time_left(random_seconds=random_level_seconds(self.history),
                                   time_left=self._deadline(step_started) - time.perf_counter(),
                                   proposal_seconds=self.proposer.projected_proposal_seconds(),
                                   picks=self._surrogate_picks(self.evals), evals_left=config.budget - self.evals,
                                   direct_variant=direct_variant(config))
        if look.direct:
            self.continue_direct(look)
        return look

    def continue_direct(self, choice: SearchChoice) -> None:
        """Records ``choice`` and hands the archive to the domain's direct search (the surrogate's proposer is dropped
        with its data). ``search = "auto"`` calls it when it chooses; ``benchmarks/bench_auto_switch_bound.py`` calls
        it right after the random iteration."""
        self.search_choice = choice
        self.proposer = DirectQD(config=direct_config(self.config), domain=self.domain, archive=self.archive,
                                 seeds=self.seeds, handover=True)

    def _step(self) -> dict[str, float]:
        started = time.perf_counter()
        # search = "auto" with a time budget looks at the time left before the surrogate's first training.
        look = (self._look_at_time_left(started) if self.config.search == "auto" and self.config.time_budget > 0
                and self.outer_iteration == 1 and self.search_choice is None else None)
        look_seconds = time.perf_counter() - started
        if self.pending is not None:  # chosen during the previous step (pipelined)
            proposal, times = self.pending, {}
            self.pending = None
        else:
            proposal = self.proposer.propose(outer_iteration=self.outer_iteration)
            times = dict(proposal.times)
        if look is not None:
            times["auto_look"] = look_seconds
        solutions = proposal.solutions[: self.config.budget - self.evals]
        seeds = [self.seeds.evaluation(self.evals + i) for i in range(len(solutions))]

        tic = time.perf_counter()
        # search = "auto": the surrogate's first picks are probed, then the rest evaluated or dropped; with a time
        # budget, the random iteration is evaluated in parts, with a look at the time left after each.
        probing = self.config.search == "auto" and self.search_choice is None and self.outer_iteration > 0
        timing_random = (self.config.search == "auto" and self.config.time_budget > 0 and self.outer_iteration == 0
                         and self.search_choice is None and not self.config.surrogate.init
                         and len(solutions) > RANDOM_LEVELS_TIMED
                         and self._surrogate_picks(self.evals + len(solutions)) > 0)
        if probing:
            proposal, results, seeds = self._probe_first_picks(proposal, solutions, seeds, started, look)
        elif timing_random:
            look, proposal, results, seeds = self._time_random_levels(proposal, solutions, seeds, started)
        else:
            evaluation = PendingEvaluation(self.evaluator, solutions, seeds, deadline=self._deadline(started),
                                           progress=self._evaluation_progress())
            # The next iteration's picks, chosen while this batch is evaluated, by a surrogate that has not seen it.
            # Not in the first iteration: the surrogate has nothing to train on until its random batch is back.
            if self.config.pipeline and self.outer_iteration > 0 and self.evals + len(solutions) < self.config.budget:
                overlap = time.perf_counter()
                self.pending = self._propose(self.outer_iteration + 1, times)
                if evaluation.overlapped:
                    times["overlapped"] = time.perf_counter() - overlap
            results = evaluation.result()
        times["evaluate"] = time.perf_counter() - tic
        solutions = proposal.solutions[:len(results)]  # a time budget (or auto's probe) may have stopped the batch
        self._record_failures(solutions, seeds, results)
        batch = EvaluatedBatch.collect(proposal, results, domain=self.domain, outer_iteration=self.outer_iteration)
        if results and not batch.ok:
            # Nothing was learned and nothing would be: a broken agent or simulator fails every batch.
            raise EvaluationsFailed(f"every evaluation of outer iteration {self.outer_iteration} failed "
                                    f"({len(results)} of {len(results)}, after retries); the first: {results[0].error}")
        new_cells = self._count_new_cells(batch.measures)
        # Read before the batch enters the archive; it changes nothing the search computes.
        self.growth = growth_curve(self.archive, measures=batch.measures, objective=batch.objective,
                                   evals_at=[self.evals + i + 1 for i in batch.ok], budget=self.config.budget)
        metrics = {**proposal.metrics, **self.proposer.learn(batch)}
        if look is not None and look.direct:
            metrics.update(look.metrics())
            if timing_random:  # the direct search continues from the random levels evaluated
                self.continue_direct(look)
        if probing and self.search_choice.direct:
            self.continue_direct(self.search_choice)

        self.evals += len(solutions)
        self.outer_iteration += 1
        if (self.config.pipeline and self.pending is None and self.evals < self.config.budget
                and not 0 < self.config.time_budget <= self.wall_time + time.perf_counter() - started):
            self.pending = self._propose(self.outer_iteration, times)
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

    def _deadline(self, step_started: float) -> float | None:
        """The :func:`time.perf_counter` value at which the time budget runs out (None: no time budget)."""
        if self.config.time_budget <= 0:
            return None
        return step_started + self.config.time_budget - self.wall_time

    def _evaluation_progress(self, offset: int = 0):
        """The evaluation bar's callback for a batch (``offset``: the part of it already evaluated this step)."""
        if self.progress is None:
            return None
        start, budget, progress = self.evals + offset, self.config.budget, self.progress
        return lambda done: progress("evaluate", start + done, budget)

    def _propose(self, outer_iteration: int, times: dict[str, float]) -> Proposal:
        """Iteration ``outer_iteration``'s proposal, made now; its phases' seconds are added to this step's ``times``."""
        proposal = self.proposer.propose(outer_iteration=outer_iteration)
        for phase, seconds in proposal.times.items():
            times[phase] = times.get(phase, 0.0) + seconds
        return proposal

    def _record_failures(self, solutions: Solutions, seeds: list[int], results: list[EvaluationResult]) -> None:
        for i, result in enumerate(results):
            if result.failed:
                self.failures.append({"eval_index": self.evals + i, "seed": seeds[i], "error": result.error,
                                      "solution": np.asarray(solutions[i]).tolist()})

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
            "search_choice": None if self.search_choice is None else self.search_choice.state_dict(),
            "pending_proposal": None if self.pending is None else self.pending.state_dict(),
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
        # Before the seeds load: the direct search's construction draws a seed the stored streams already account for.
        self.search_choice = SearchChoice.from_state_dict(state.get("search_choice"))
        if self.search_choice is not None and self.search_choice.direct:
            self.continue_direct(self.search_choice)
        self.seeds.load_state_dict(state)
        self.archive = state["archive"]
        self.proposer.load_state_dict(state)
        pending = state.get("pending_proposal")  # absent from checkpoints of unpipelined versions
        self.pending = None if pending is None else Proposal.from_state_dict(pending)
