"""Where an outer iteration's levels come from: the strategies the DSAGE loop is written against.

A :class:`~dsage_ray.core.proposal.Proposer` proposes the solutions to evaluate for real and learns from their
results (its records, :class:`Proposal` and :class:`EvaluatedBatch`, are in :mod:`dsage_ray.core.proposal` and
importable from here too):

* :class:`SurrogateAssisted` — DSAGE (the paper's Algorithm 1, docs/ALGORITHM.md): train the surrogate on the
  dataset, exploit it with a fresh inner QD loop, select from the surrogate archive. Its first iteration
  proposes ``n_rand`` random solutions.
* :class:`DirectQD` — a QD optimizer on the ground-truth archive: MAP-Elites, CMA-ME or, with the
  random emitter, domain randomisation (DR).

Both insert what was evaluated into the ground-truth archive, each in its own way (the direct
optimizer's ``tell`` does it; DSAGE adds, then grows its dataset).
"""

from __future__ import annotations

import dataclasses
import time
from typing import TYPE_CHECKING, Any

import numpy as np

from dsage_ray.config import RunConfig
from dsage_ray.core.holdout import HeldOutLevels, head_label
from dsage_ray.core.proposal import EvaluatedBatch, ProgressCallback, Proposal, Proposer
from dsage_ray.core.screening import ScreenStep
from dsage_ray.qd.archives import make_archive
from dsage_ray.qd.mutants import elite_mutants
from dsage_ray.qd.emitters import RandomEmitter
from dsage_ray.qd.optimizer import (EMITTERS_WITH_OWN_START, MAP_ELITES_RANDOM_BATCHES, compile_emitters,
                                   make_scheduler, reopened_scheduler, run_inner_loop)
from dsage_ray.qd.selection import additions, gather_elites, select_solutions
from dsage_ray.surrogate.models import encode_solutions
from dsage_ray.types import Domain, Evaluator, Solutions, solution_bounds

if TYPE_CHECKING:
    from ribs.archives import GridArchive

    from dsage_ray.core.seeds import RunSeeds

__all__ = ["DirectQD", "EvaluatedBatch", "ProgressCallback", "Proposal", "Proposer", "SurrogateAssisted",
           "domain_archive"]


def domain_archive(domain: Domain, *, with_occupancy: bool, seed: int) -> "GridArchive":
    """An empty archive over ``domain``'s measures (the ground truth keeps each elite's occupancy)."""
    return make_archive(solution_dim=domain.solution_dim, dims=domain.archive_dims, ranges=domain.measure_ranges,
                        occupancy_shape=domain.occupancy_shape if with_occupancy else None, seed=seed,
                        solution_dtype=domain.solution_dtype)


class DirectQD(Proposer):
    """MAP-Elites, CMA-ME, DR or a continuous search (``qd.emitter``): the configured QD optimizer asks for solutions
    and is told their real results.

    With ``selection.screen_episodes`` (MAP-Elites only), each batch after the random start-up is instead chosen
    from ``experimental.screen_pool`` times as many mutants of the archive's elites by the domain's screen
    (:func:`~dsage_ray.qd.screen.keep_screened`), and added to the archive directly: MAP-Elites' emitters sample
    parents from the archive and keep no state that a ``tell`` would update.

    Args:
        config: The run's config (``qd``: emitter, batch sizes; ``selection``: the screen).
        domain: The domain.
        archive: The ground-truth archive the optimizer fills.
        seeds: The run's seed streams.
        handover: It takes over a run that began as DSAGE (``search = "auto"``), with levels in ``archive``
            already. It then asks what a run of it from the start would have asked: its scheduler draws that run's
            seed, and emitters with a start of their own (:data:`~dsage_ray.qd.optimizer.EMITTERS_WITH_OWN_START`)
            read an archive of their own, while every level still enters ``archive``. Otherwise CMA-ME would rank
            against, and restart from, DSAGE's random levels, and ``auto`` would not be the fixed choice started late.
    """

    def __init__(self, *, config: RunConfig, domain: Domain, archive: "GridArchive", seeds: "RunSeeds",
                 handover: bool = False) -> None:
        self.config = config
        self.archive = archive
        self.seeds = seeds
        self.random_solutions = domain.random_solutions
        #: The box the domain's solutions live in (:class:`~dsage_ray.types.BoundedDomain`; ``None``: unbounded).
        self.solution_bounds = solution_bounds(domain)
        emitters_archive = archive
        if handover:
            archive_seed, seed = seeds.first_qd_seeds()
            if config.qd.emitter in EMITTERS_WITH_OWN_START:
                emitters_archive = domain_archive(domain, with_occupancy="occupancy" in archive.field_list,
                                                  seed=archive_seed)
        else:
            seed = seeds.next_qd_seed()
        self.scheduler = make_scheduler(emitters_archive, config=config.qd, solution_dim=domain.solution_dim,
                                        random_solutions=domain.random_solutions, seed=seed,
                                        bounds=self.solution_bounds, result_archive=archive)
        #: Chooses each batch after the random start-up among screened mutants (None: no screen).
        self.screen = ScreenStep.for_run(config=config, domain=domain, seeds=seeds)
        #: Whether the batch under evaluation came from the scheduler (then it is told), not from a screen.
        self.asked = True

    def propose(self, *, outer_iteration: int) -> Proposal:
        qd = self.config.qd
        self.asked = (self.screen is None or outer_iteration < MAP_ELITES_RANDOM_BATCHES
                      or self.archive.empty)
        if self.asked:
            return Proposal(self.scheduler.ask())
        # MAP-Elites' own step (uniform parents, its mutation), screened: a larger batch of mutants, of which
        # those whose screened result adds to the archive are evaluated (its emitters keep no state to tell).
        tic = time.perf_counter()
        batch = qd.num_emitters * qd.batch_size
        mutants = elite_mutants(self.archive, count=int(round(self.config.experimental.screen_pool * batch)),
                                share=1.0, qd=qd, rng=self.seeds.rng, bounds=self.solution_bounds)
        kept, estimates, metrics = self.screen.keep(mutants, self.archive, limit=batch)
        seconds = time.perf_counter() - tic
        return Proposal(mutants[kept], metrics=metrics, times={"select": seconds, "screen": seconds},
                        screened=estimates)

    def learn(self, batch: EvaluatedBatch) -> dict[str, float]:
        if self.asked and batch.complete:
            # The emitters need the whole batch they asked for; tell() also adds to the archives.
            self.scheduler.tell(batch.objective, batch.measures, occupancy=batch.occupancy)
            return {}
        if batch.ok:
            # The run's archive, and the emitters' own where they have one (after a handover).
            for archive in {id(a): a for a in (self.archive, self.scheduler.archive)}.values():
                archive.add(batch.solutions[batch.ok], batch.objective, batch.measures, occupancy=batch.occupancy)
        if not self.asked:
            self.screen.learn(batch)
        else:
            # A batch with failed (or budget-truncated) evaluations cannot be told.
            self.scheduler = reopened_scheduler(self.scheduler)
        return {}

    def state_dict(self) -> dict[str, Any]:
        return {"scheduler": self.scheduler, "surrogate": None, "dataset": None, "holdout": None, "holdout_evals": 0,
                "screen_errors": None if self.screen is None else self.screen.state_dict()}

    def load_state_dict(self, state: dict[str, Any]) -> None:
        self.scheduler = state["scheduler"]
        for emitter in self.scheduler.emitters:
            if isinstance(emitter, RandomEmitter):  # its sampler is the domain's code, not in the checkpoint
                emitter.attach(self.random_solutions)
        self.archive = state["archive"]
        if self.screen is not None:
            self.screen.load_state_dict(state.get("screen_errors"))


class SurrogateAssisted(Proposer):
    """DSAGE's proposals: train the surrogate, exploit it with an inner QD loop, select from its archive.

    Args:
        config: The run's config (``surrogate``, ``qd``, ``selection``, ``n_rand``).
        domain: The domain.
        archive: The ground-truth archive (``selection.elite_mutants`` and the screen read it; :meth:`learn`
            fills it).
        seeds: The run's seed streams.
        evaluator: Evaluates the held-out levels, if any.
        progress: Optional progress callback (``holdout``, ``exploit`` phases).

    Attributes:
        last_predictions: ``(predicted_measures, true_measures)`` of the batch learned last (Fig. 9 scatter).
    """

    def __init__(self, *, config: RunConfig, domain: Domain, archive: "GridArchive", seeds: "RunSeeds",
                 evaluator: Evaluator, progress: ProgressCallback | None = None) -> None:
        from dsage_ray.surrogate import Surrogate

        self.config = config
        self.domain = domain
        self.archive = archive
        self.seeds = seeds
        self.evaluator = evaluator
        self.progress = progress
        self.surrogate = Surrogate.for_domain(domain, config=config.surrogate, seed=seeds.next_qd_seed())
        # The dataset keeps each level's solution too where the elite mutants' parents are drawn among them.
        keep = config.selection.elite_mutants and config.experimental.mutant_parents == "evaluated"
        self.dataset = self.surrogate.make_dataset(
            **({"solution_dim": domain.solution_dim, "solution_dtype": domain.solution_dtype} if keep else {}))
        self.holdout = HeldOutLevels(count=config.experimental.holdout_levels, domain=domain, seeds=seeds)
        self.last_predictions: tuple[np.ndarray, np.ndarray] | None = None
        #: Samples of the dataset that came from ``surrogate.init`` (the oldest ones), not from this run.
        self.prior_samples = 0
        #: Screens the picks and more surrogate elites before their evaluation (None: no screen).
        self.screen = ScreenStep.for_run(config=config, domain=domain, seeds=seeds)
        #: Every measure is exact, so each pick's cell is known: each block's pick is the elite expected to add most
        #: to the ground-truth archive, not a uniform draw (docs/results/gym_audit).
        self.cells_known = self.surrogate.measures_exact

    def propose(self, *, outer_iteration: int) -> Proposal:
        proposal = Proposal(np.empty(0))
        if outer_iteration == 0:
            if self.holdout.pending:
                tic = time.perf_counter()
                self.holdout.evaluate(self.evaluator, progress=self.progress)
                proposal.times["holdout"] = time.perf_counter() - tic
            if not self.config.surrogate.init:
                proposal.solutions = self.domain.random_solutions(self.config.n_rand, self.seeds.rng)
                return proposal
            tic = time.perf_counter()
            proposal.metrics.update(self._warm_start())
            proposal.times["train"] = time.perf_counter() - tic
        else:
            tic = time.perf_counter()
            proposal.metrics.update(self._train())
            proposal.times["train"] = time.perf_counter() - tic
        if self.holdout.data is not None:
            tic = time.perf_counter()
            proposal.metrics.update(self.holdout.score(self.surrogate))
            proposal.times["holdout"] = time.perf_counter() - tic
        tic = time.perf_counter()
        if compile_emitters(config=self.config.qd, solution_dim=self.domain.solution_dim,
                            solution_dtype=self.domain.solution_dtype, random_solutions=self.domain.random_solutions):
            proposal.times["compile"] = time.perf_counter() - tic
        tic = time.perf_counter()
        surrogate_archive = self._exploit()
        proposal.times["exploit"] = time.perf_counter() - tic
        tic = time.perf_counter()
        proposal.solutions, proposal.screened = self._select(surrogate_archive, proposal.metrics, proposal.times)
        if self.config.selection.elite_mutants:
            self._add_elite_mutants(proposal)
        proposal.predicted = self.surrogate.predict(encode_solutions(self.domain, proposal.solutions))
        proposal.times["select"] = time.perf_counter() - tic
        proposal.metrics["surrogate_archive_size"] = float(len(surrogate_archive))
        return proposal

    def learn(self, batch: EvaluatedBatch) -> dict[str, float]:
        metrics: dict[str, float] = {}
        encoded = encode_solutions(self.domain, batch.solutions)
        if self.screen is not None:
            self.screen.learn(batch)
        if batch.ok:
            self.archive.add(batch.solutions[batch.ok], batch.objective, batch.measures, occupancy=batch.occupancy)
            self.dataset.append(encoded=encoded, results=batch.results,
                                solutions=None if self.dataset.solution_dim is None else batch.solutions)
            # A cold start's first batch is random: nothing was predicted for it.
            if batch.predicted is not None:
                errors = self.surrogate.mae(encoded, batch.results, prediction=batch.predicted)
                metrics.update({f"mae_{self._label(k)}": v for k, v in errors.items()})
                self.last_predictions = (batch.predicted.measures[batch.ok], batch.measures)
        return metrics

    def projected_proposal_seconds(self) -> float:
        """Seconds the next proposal's training and inner loop are projected to take, before either runs.

        One training step (on a copy of the model) times the epochs' steps; one inner-loop batch (random solutions,
        encoded and predicted) times ``qd.exploit_iterations``. Nothing the run computes changes: the solutions
        come from a generator of their own, not from the run's streams. Pyribs' own work is left out, so this is
        a little under what the proposal will take.
        """
        config = self.config
        window = min(config.surrogate.train_window, len(self.dataset))
        steps = config.surrogate.epochs * -(-window // config.surrogate.batch_size)
        train = steps * self.surrogate.training_step_seconds(self.dataset)
        solutions = self.domain.random_solutions(config.qd.num_emitters * config.qd.batch_size,
                                                 np.random.default_rng(0))
        batch = 0.0
        for _ in range(2):  # the second is timed: the first carries one-off allocations
            tic = time.perf_counter()
            self.surrogate.predict(encode_solutions(self.domain, solutions))
            batch = time.perf_counter() - tic
        return train + config.qd.exploit_iterations * batch

    # ---------------------------------------------------------------------------------- phases

    def _train(self) -> dict[str, float]:
        """Model improvement: trains on the most recent evaluations (weights and Adam state persist)."""
        losses = self.surrogate.train(self.dataset)
        metrics = {"surrogate_loss": losses.pop("total"), "surrogate_epochs": losses.pop("epochs")}
        metrics.update({f"surrogate_loss_{self._label(k)}": v for k, v in losses.items()})
        return metrics

    def _warm_start(self) -> dict[str, float]:
        """Loads ``surrogate.init``'s weights (and, with ``experimental.init_prior``, its dataset) before the first
        exploit."""
        from dsage_ray.core.warm_start import load_warm_start

        source = load_warm_start(self.config.surrogate.init)
        source.check_compatible(self.config, level_shape=self.dataset.level_shape)
        self.surrogate.model.load_state_dict(source.surrogate["model"])
        if self.config.experimental.init_prior:
            self.dataset.load_state_dict({key: source.dataset[key] for key in (
                "levels", "objective", "measures", "occupancy")} | {"level_shape": self.dataset.level_shape})
            self.prior_samples = len(self.dataset)
        return {"prior_samples": float(self.prior_samples)}

    def _exploit(self) -> "GridArchive":
        """Model exploitation: a fresh surrogate archive and fresh emitters, ``qd.exploit_iterations`` ask → predict → tell."""
        archive = domain_archive(self.domain, with_occupancy=False, seed=self.seeds.next_qd_seed())
        scheduler = make_scheduler(archive, config=self.config.qd, solution_dim=self.domain.solution_dim,
                                   random_solutions=self.domain.random_solutions, seed=self.seeds.next_qd_seed(),
                                   bounds=solution_bounds(self.domain))

        def predict(solutions: Solutions):
            prediction = self.surrogate.predict(encode_solutions(self.domain, solutions))
            return prediction.objective, prediction.measures, {}

        progress = None
        if self.progress is not None:
            total = self.config.qd.exploit_iterations
            done = iter(range(1, total + 1))
            # run_inner_loop reports one increment per iteration; our callback takes a running count.
            progress = lambda _increment: self.progress("exploit", next(done), total)  # noqa: E731
        run_inner_loop(scheduler, predict, self.config.qd.exploit_iterations, progress=progress)
        return archive

    def _select(self, surrogate_archive: "GridArchive", metrics: dict[str, float],
                times: dict[str, float]) -> tuple[Solutions, np.ndarray | None]:
        """Selection: downsample / random / full picks from the surrogate archive, and their screened results
        (None: no screen; ``times["screen"]``: the part of it spent screening them)."""
        selection = self.config.selection
        among, gain = self._picks_that_add(surrogate_archive, metrics)
        picks = select_solutions(surrogate_archive, method=selection.method, block=selection.block,
                                 count=selection.count, rng=self.seeds.rng, among=among, priority=gain)
        estimates = None
        if self.screen is not None:
            picks, estimates = self.screen.screen_picks(surrogate_archive, picks, self.archive, rng=self.seeds.rng,
                                                        metrics=metrics, times=times)
        return gather_elites(surrogate_archive, picks)["solution"], estimates

    def _picks_that_add(self, surrogate_archive: "GridArchive",
                        metrics: dict[str, float]) -> tuple[np.ndarray | None, np.ndarray | None]:
        """With known cells, or an ``experimental.min_predicted`` floor: the surrogate elites whose predicted objective
        would enter the ground-truth archive (a new cell, or more than its elite; of those at least the floor, where
        any is) and what each would add to its QD-score, so that each block's pick is its largest gain.
        ``(None, None)`` (every elite, uniformly) when cells are predicted without a floor, or none would enter."""
        floor = self.config.experimental.min_predicted
        if not self.cells_known and floor == 0.0:
            return None, None
        data = surrogate_archive.data()
        adding, gain = additions(self.archive, data["objective"], data["measures"])
        if floor != 0.0 and (good := adding & (np.asarray(data["objective"]) >= floor)).any():
            adding = good
        metrics["selection_elites_that_add"] = float(adding.sum())
        if not adding.any():
            return None, None
        return np.asarray(data["index"])[adding], gain[adding]

    def _add_elite_mutants(self, proposal: Proposal) -> None:
        """Mutants of the ground truth's best elites beside the picks (``selection.elite_mutants``), unscreened."""
        qd = self.config.qd
        if self.config.experimental.mutant_sigma:
            qd = dataclasses.replace(qd, sigma0=self.config.experimental.mutant_sigma)
        mutants = elite_mutants(self.archive, count=self.config.selection.elite_mutants,
                                share=self.config.experimental.elite_share, qd=qd, rng=self.seeds.rng,
                                bounds=solution_bounds(self.domain),
                                evaluated=None if self.dataset.solutions is None else (self.dataset.solutions,
                                                                                       self.dataset.objective))
        proposal.solutions = np.concatenate([proposal.solutions, mutants])
        if proposal.screened is not None:
            proposal.screened = np.concatenate([proposal.screened,
                                                np.full((len(mutants), proposal.screened.shape[1]), np.nan)])
        proposal.metrics["selection_elite_mutants"] = float(len(mutants))

    def _label(self, head: str) -> str:
        return head_label(head, self.domain.measure_names)

    # ----------------------------------------------------------------------------------- state

    def state_dict(self) -> dict[str, Any]:
        return {"scheduler": None, "surrogate": self.surrogate.state_dict(), "dataset": self.dataset.state_dict(),
                "prior_samples": self.prior_samples,
                "screen_errors": None if self.screen is None else self.screen.state_dict(),
                **self.holdout.state_dict()}

    def load_state_dict(self, state: dict[str, Any]) -> None:
        self.archive = state["archive"]
        self.surrogate.load_state_dict(state["surrogate"])
        self.dataset.load_state_dict(state["dataset"])
        self.prior_samples = state.get("prior_samples", 0)
        if self.screen is not None:
            self.screen.load_state_dict(state.get("screen_errors"))
        self.holdout.load_state_dict(state)
        self.last_predictions = state["last_predictions"]
