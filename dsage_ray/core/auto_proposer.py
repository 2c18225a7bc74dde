"""``search = "auto"``: a proposer that begins as DSAGE and hands the archive to the domain's direct search once what
the surrogate costs says it does not pay.

:class:`AutoSearch` wraps both. It looks at the costs at three moments and decides by the rules of
:mod:`dsage_ray.core.auto_search` (why each is what it is, with the measurements, is there):

1. With a time budget, during the random first iteration: it is evaluated in parts of :data:`RANDOM_LEVELS_TIMED`
   levels (or one per simulator, if more), and after each the rest is projected at the seconds of the levels so far
   (:func:`~dsage_ray.core.auto_search.choose_during_random`). Where the rest would leave too little time for the
   surrogate, it is dropped; the levels evaluated are learned and the direct search continues from them.
2. With a time budget, right after the random iteration, before the surrogate first trains: its first proposal is
   projected (:meth:`~dsage_ray.core.proposers.SurrogateAssisted.projected_proposal_seconds`) and the direct search
   takes over at once where too few surrogate iterations fit in the time left
   (:func:`~dsage_ray.core.auto_search.choose_by_time_left`).
3. Otherwise the first surrogate iteration's picks are probed: :data:`PROBE_PICKS` of them, spread over the picks'
   order (they come in archive order, where a region of cheap levels may come first), are evaluated first, stopped
   once they alone cost past the break-even (:func:`~dsage_ray.core.auto_search.probe_allowance`); then the choice
   (:func:`~dsage_ray.core.auto_search.choose_search`). Above the break-even the rest is dropped, the probed picks
   are learned, and the direct search continues; below it the rest is evaluated and the run is DSAGE's, bit for bit.

The direct search that takes over (:class:`~dsage_ray.core.proposers.DirectQD` with ``handover``, built from
:func:`~dsage_ray.core.auto_search.direct_config`) asks what a run of it from the start would have asked, while every
level enters the run's archive. The choice is part of the run's state (``search_choice``) and of the metrics row of
the iteration it was made in (:meth:`~dsage_ray.core.auto_search.SearchChoice.metrics`).
"""

from __future__ import annotations

import time
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np

from dsage_ray.config import RunConfig
from dsage_ray.core.auto_search import (SearchChoice, choose_by_time_left, choose_during_random, choose_search,
                                        direct_config, direct_variant, probe_allowance, random_level_seconds)
from dsage_ray.core.proposal import EvaluatedBatch, Proposal, ProposerWrapper, Simulation
from dsage_ray.core.proposers import DirectQD, SurrogateAssisted
from dsage_ray.types import Domain

if TYPE_CHECKING:
    from ribs.archives import GridArchive

    from dsage_ray.core.seeds import RunSeeds

#: Picks evaluated before the choice: enough to average a pick's evaluation, few where each is slow (Mario).
PROBE_PICKS = 8

#: With a time budget, the random first iteration is evaluated in parts of this many levels (or one per simulator,
#: if more), with a look after each: level times are heavy-tailed (Mario's A* plays most random levels in a second,
#: a few in half a minute), so one look after the first few can miss a slow iteration. Mario's random levels took
#: 35-57% of 10 minutes on seeds 96-98, and the look after them came too late.
RANDOM_LEVELS_TIMED = 8

#: The phases of a surrogate proposal that its cost counts (``Proposal.times``; held-out levels are not the search's).
SURROGATE_PHASES = ("train", "exploit", "select")


class RunSoFar(Protocol):
    """What ``search = "auto"`` reads of its run (:class:`~dsage_ray.core.runner.DSAGE`)."""

    #: Real evaluations spent.
    evals: int
    #: One metrics row per outer iteration done; the first is the random iteration's.
    history: list[dict[str, float]]

    def time_left(self) -> float | None:
        """Seconds of the time budget left now (None: no time budget)."""


class AutoSearch(ProposerWrapper):
    """DSAGE until a look at the costs chooses the domain's direct search, which then continues on the same archive.

    Args:
        dsage: DSAGE's proposer, which proposes until the choice.
        config: The run's config (``search = "auto"``).
        domain: The domain.
        archive: The ground-truth archive, which the direct search continues.
        seeds: The run's seed streams.
        run: The run it decides for: its evaluations, metrics rows and time left.

    Attributes:
        inner: The proposer that proposes now: ``dsage``, then the direct search if it was chosen.
        choice: What it chose, once it has (None: not yet).
    """

    def __init__(self, *, dsage: SurrogateAssisted, config: RunConfig, domain: Domain, archive: "GridArchive",
                 seeds: "RunSeeds", run: RunSoFar) -> None:
        self.inner: SurrogateAssisted | DirectQD = dsage
        self.config = config
        self.domain = domain
        self.archive = archive
        self.seeds = seeds
        self.run = run
        self.choice: SearchChoice | None = None
        self._outer_iteration = 0
        #: This iteration's look by the time budget (None: none), which ``learn`` reports where it chose.
        self._look: SearchChoice | None = None

    # ------------------------------------------------------------------------------------ proposer

    def propose(self, *, outer_iteration: int) -> Proposal:
        self._outer_iteration, self._look = outer_iteration, None
        tic = time.perf_counter()
        if outer_iteration == 1 and self.choice is None and self.config.time_budget > 0:
            self._look = self._look_at_time_left()
        seconds = time.perf_counter() - tic
        proposal = self.inner.propose(outer_iteration=outer_iteration)
        if self._look is not None:
            proposal.times["auto_look"] = seconds
        return proposal

    def evaluate(self, simulation: Simulation) -> None:
        if self.choice is None and self._outer_iteration > 0:
            self._probe_first_picks(simulation)
        elif (self.config.time_budget > 0 and self._outer_iteration == 0 and self.choice is None
              and not self.config.surrogate.init and simulation.count > RANDOM_LEVELS_TIMED
              and self.surrogate_picks(simulation.evals + simulation.count) > 0):
            self._time_random_levels(simulation)
        else:
            self.inner.evaluate(simulation)

    def learn(self, batch: EvaluatedBatch) -> dict[str, float]:
        metrics = self.inner.learn(batch)
        if self._look is not None and self._look.direct:
            metrics.update(self._look.metrics())
        if self.choice is not None and self.choice.direct and not isinstance(self.inner, DirectQD):
            self.continue_direct(self.choice)  # after what was evaluated is learned: the direct search continues it
        return metrics

    def continue_direct(self, choice: SearchChoice) -> None:
        """Records ``choice`` and hands the archive to the domain's direct search (DSAGE's proposer is dropped with
        its data). The looks call it when they choose; ``benchmarks/bench_auto_switch_bound.py`` calls it right after
        the random iteration."""
        self.choice = choice
        self.inner = DirectQD(config=direct_config(self.config), domain=self.domain, archive=self.archive,
                              seeds=self.seeds, handover=True)

    def surrogate_picks(self, evals: int) -> int:
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

    # ------------------------------------------------------------------------------------- looks

    def _look_at_time_left(self) -> SearchChoice:
        """Before the first surrogate proposal: the direct search continues at once where too few surrogate
        iterations, at their cheapest, fit in the time left."""
        evals = self.run.evals
        look = choose_by_time_left(random_seconds=random_level_seconds(self.run.history),
                                   time_left=self.run.time_left(),
                                   proposal_seconds=self.inner.projected_proposal_seconds(),
                                   picks=self.surrogate_picks(evals), evals_left=self.config.budget - evals,
                                   direct_variant=direct_variant(self.config))
        if look.direct:
            self.continue_direct(look)
        return look

    def _time_random_levels(self, simulation: Simulation) -> None:
        """The random first iteration in parts, with a look after each: where the rest, at the seconds of the levels
        so far, would leave too little time for the surrogate, the rest is dropped. What is evaluated is a prefix of
        the batch: with every level evaluated, the batch exactly as one evaluation gives it."""
        count = simulation.count
        part = max(RANDOM_LEVELS_TIMED, int(getattr(simulation.evaluator, "num_workers", 1)))
        tic = time.perf_counter()
        while len(simulation.results) < count:
            first = len(simulation.results)
            stop = min(first + part, count)
            got = simulation.evaluate(slice(first, stop))
            if len(got) < stop - first or len(simulation.results) == count:  # the time budget stopped it, or done
                return
            look = choose_during_random(seconds=time.perf_counter() - tic, timed=len(simulation.results),
                                        random_levels=count, time_left=simulation.time_left(),
                                        picks=self.surrogate_picks(simulation.evals + count),
                                        evals_left=simulation.budget - simulation.evals - count,
                                        direct_variant=direct_variant(self.config))
            if look.direct:
                self._look = self.choice = look
                return

    def _probe_first_picks(self, simulation: Simulation) -> None:
        """Evaluates :data:`PROBE_PICKS` of the surrogate's first picks, spread over their order, chooses, then
        evaluates the rest or drops it. This iteration's look at the time left, which kept DSAGE, is carried into
        the choice. With every pick evaluated, the fixed run's batch exactly."""
        tic, count, proposal = time.perf_counter(), simulation.count, simulation.proposal
        probe = sorted({int(i) for i in np.linspace(0, count - 1, min(PROBE_PICKS, count)).round()})
        surrogate_seconds = sum(proposal.times.get(phase, 0.0) for phase in SURROGATE_PHASES)
        # The probe stops once its picks alone have cost more than the break-even allows (Mario's A* may play a
        # pick for half a minute): the choice is then made already.
        allowance = probe_allowance(self.run.history, surrogate_seconds=surrogate_seconds, picks=count,
                                    probed=len(probe))
        simulation.evaluate(probe, deadline=tic + allowance)
        self.choice = choose_search(self.run.history, surrogate_seconds=surrogate_seconds, picks=count,
                                    probe_seconds=time.perf_counter() - tic, probed=len(simulation.results),
                                    direct_variant=direct_variant(self.config), before=self._look)
        proposal.metrics.update(self.choice.metrics())
        rest = [i for i in range(count) if i not in simulation.results]
        if not self.choice.direct and len(simulation.results) == len(probe) and rest:
            simulation.evaluate(rest)

    # ------------------------------------------------------------------------------------- state

    def state_dict(self) -> dict[str, Any]:
        return {**self.inner.state_dict(),
                "search_choice": None if self.choice is None else self.choice.state_dict()}

    def load_state_dict(self, state: dict[str, Any]) -> None:
        self.archive = state["archive"]
        choice = SearchChoice.from_state_dict(state.get("search_choice"))
        if choice is not None and choice.direct:
            self.continue_direct(choice)
        self.choice = choice
        self.inner.load_state_dict(state)
