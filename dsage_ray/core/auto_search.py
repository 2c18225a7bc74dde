"""``search = "auto"``: keep DSAGE, or continue with the domain's direct QD search, by what the surrogate costs.

DSAGE buys better levels per evaluation with time: the surrogate's training, inner loop and selection, and, where its
picks are harder levels than random ones, their slower evaluation (Mario's A* plays DSAGE's picks 5× slower than
random levels). Where that time is large next to what a level costs, a direct QD search (MAP-Elites, CMA-ME, a
falsifier) evaluates many more levels in the same time and finds more. The benchmarks put the break-even on what a
pick costs, all of that included, over what a random level's evaluation costs:

* Maze (the ``cpu`` preset, ACCEL): 1.7-2.4×, and DSAGE led MAP-Elites at equal CPU time (1.15×,
  docs/DECISIONS.md);
* CartPole and LunarLander (the published audits): 1.5-2.0×, and DSAGE was the better search at equal CPU time
  (docs/results/gym_audit);
* Mario (A*, the ``cpu`` preset): about 16×, and CMA-ME found twice DSAGE's QD-score at equal CPU time
  (docs/DECISIONS.md; without JPype's collector link: DSAGE 0.51 ± 0.11× CMA-ME).

With a time budget, the choice can come before the surrogate ever trains (:func:`choose_during_random`,
:func:`choose_by_time_left`): where fewer than :data:`MIN_SURROGATE_ITERATIONS` surrogate iterations, at their
cheapest, fit in the time left, the direct search takes over at once. DSAGE's first model has seen only random levels,
and it cannot pay for its training in the one or two iterations left to it. On Mario at 10 minutes the probe comes 4-7
minutes into the run, too late for the direct search to catch up (0.32-0.72× CMA-ME), while the same random levels
followed at once by CMA-ME did as well as CMA-ME from the start (docs/DECISIONS.md). Where the random levels
themselves take much of the budget, a look after them comes too late as well (Mario seeds 96-98: they took 35-57% of
10 minutes, and ``auto`` reached 0.51× CMA-ME), hence looks during them (Mario seeds 108-110: a switch 22-32 s in,
1.00 ± 0.07× CMA-ME). Without a time budget nothing limits the iterations, and only the probe of the first surrogate
picks decides (:func:`choose_search`): above :data:`BREAK_EVEN_COST_RATIO` times a random level's evaluation, the
direct search continues. So a domain where DSAGE does not pay loses one surrogate proposal and a few picks.

The direct search that takes over asks what a run of it from the start would have asked
(:class:`~dsage_ray.core.proposers.DirectQD` with ``handover``), so ``auto`` trails the fixed direct search by the time
spent before the switch and keeps the levels played before it (on Mario seeds 108-110 it played 1,262 ± 52 levels in
10 minutes, CMA-ME from the start 1,236 ± 52). The seconds are wall seconds, so a run with more simulators (a Ray
pool: each level cheaper in wall time, the surrogate not) leans to the direct search, as it should at equal wall time.
Like a time budget, the choice depends on the machine: an ``auto`` run is reproducible given its choice (part of the
run's state and of its metrics), not across machines.

When each look comes, and what it evaluates first, is :class:`~dsage_ray.core.auto_proposer.AutoSearch`'s, the
proposer ``search = "auto"`` runs.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any, Mapping, Sequence

from dsage_ray.config import RunConfig, variants
from dsage_ray.domains.registry import get_domain

#: Above this ratio (seconds per pick, surrogate and evaluation included / seconds per random level) the run
#: continues with the direct search. Above the ratios where DSAGE won at equal CPU time (Maze up to 2.4, CartPole
#: and LunarLander up to 2.0), below Mario's (about 16), where it lost by half.
BREAK_EVEN_COST_RATIO = 3.0

#: With a time budget, fewer surrogate iterations than this fitting in the time left after the random iteration (each at
#: its cheapest: the projected proposal, then its picks at a random level's seconds) sends the run to the direct
#: search before the surrogate trains; fewer are needed where fewer spend the rest of the evaluation budget. Not tuned
#: (set before any run read it): on Mario with 10 minutes 0.9-1.5 fit, on the Maze's ``cpu`` preset with 10 minutes 32,
#: in a CartPole ``demo`` audit with 5 minutes 4.2 (docs/DECISIONS.md; counted then at
#: ``selection.count`` picks an iteration, 432 where the gym archive has 25 blocks, so more fit in that audit now).
MIN_SURROGATE_ITERATIONS = 3

@dataclasses.dataclass(frozen=True)
class SearchChoice:
    """What ``search = "auto"`` chose, and why.

    Attributes:
        direct: The run continues with :attr:`variant` (the domain's direct search); else it stays DSAGE.
        variant: The direct search's variant name (whether or not it was chosen).
        cost_ratio: ``surrogate_level_seconds / random_level_seconds``.
        random_level_seconds: Wall seconds per level of the random first iteration's evaluation.
        surrogate_level_seconds: A pick's projected wall seconds in the first surrogate iteration: the surrogate's
            proposal (training, inner loop, selection) over all its picks, plus the probe picks' mean evaluation.
            Chosen by the time left (:func:`choose_by_time_left`): the projected proposal over the picks, plus a
            random level's evaluation.
        iterations_left: With a time budget, how many surrogate iterations at their cheapest fit in the time left
            after the random iteration (None: no time budget).
        time_left: Wall seconds of the time budget left after the random iteration (None: no time budget).
        random_levels_timed: Where the choice came during the random iteration: the levels it was timed on, the rest
            projected at their seconds (None: after the whole random iteration).
        iterations_needed: With a time budget, the surrogate iterations DSAGE needs: :data:`MIN_SURROGATE_ITERATIONS`,
            or fewer where fewer spend the rest of the evaluation budget (None: :data:`MIN_SURROGATE_ITERATIONS`).
    """

    direct: bool
    variant: str
    cost_ratio: float
    random_level_seconds: float
    surrogate_level_seconds: float
    iterations_left: float | None = None
    time_left: float | None = None
    random_levels_timed: int | None = None
    iterations_needed: float | None = None

    @property
    def by_time_left(self) -> bool:
        """Chosen before the surrogate trained, because too few of its iterations fit in the time budget."""
        return self.iterations_left is not None and self.iterations_left < self.needed

    @property
    def needed(self) -> float:
        """Surrogate iterations DSAGE needs in the time left (:attr:`iterations_needed`)."""
        return MIN_SURROGATE_ITERATIONS if self.iterations_needed is None else self.iterations_needed

    @property
    def reason(self) -> str:
        """One line for the log: the choice and the numbers it was made on."""
        if self.by_time_left:
            iteration = self.time_left / max(self.iterations_left, 1e-9)
            room = (f"room for {self.iterations_left:.1f} surrogate iterations of at least {iteration:.0f} s; "
                    f"DSAGE needs {self.needed:g}")
            if self.random_levels_timed is not None:
                after = (f"would leave {self.time_left:.0f} s, {room}" if self.time_left > 0
                         else "would use up the time budget")
                return (f"search auto: continuing with {self.variant} on the same archive after "
                        f"{self.random_levels_timed} random levels (they took {self.random_level_seconds:.3g} s each: "
                        f"the rest of the random iteration {after})")
            return (f"search auto: continuing with {self.variant} on the same archive (the time budget leaves "
                    f"{self.time_left:.0f} s, {room})")
        numbers = (f"a pick costs {self.surrogate_level_seconds:.3g} s with the surrogate's time, a random level "
                   f"{self.random_level_seconds:.3g} s: {self.cost_ratio:.2f}×; break-even {BREAK_EVEN_COST_RATIO:g}×")
        if self.direct:
            return f"search auto: continuing with {self.variant} on the same archive ({numbers})"
        return f"search auto: staying with DSAGE ({numbers})"

    def metrics(self) -> dict[str, float]:
        """The choice as metrics columns of the row it was made after (TensorBoard, ``metrics.json``, Tune)."""
        metrics = {"auto_direct": float(self.direct), "auto_cost_ratio": self.cost_ratio,
                   "auto_random_level_s": self.random_level_seconds,
                   "auto_picked_level_s": self.surrogate_level_seconds}
        if self.iterations_left is not None:
            metrics.update(auto_iterations_left=self.iterations_left, auto_time_left_s=self.time_left)
        if self.random_levels_timed is not None:
            metrics.update(auto_random_levels_timed=float(self.random_levels_timed))
        if self.iterations_needed is not None:
            metrics.update(auto_iterations_needed=float(self.iterations_needed))
        return metrics

    @classmethod
    def from_metrics(cls, row: Mapping[str, Any], *, variant: str) -> "SearchChoice | None":
        """The choice a metrics row (a Tune result) carries, None where it has none: its :meth:`metrics` columns."""
        if "auto_cost_ratio" not in row:
            return None
        return cls(direct=bool(row["auto_direct"]), variant=variant, cost_ratio=float(row["auto_cost_ratio"]),
                   random_level_seconds=float(row["auto_random_level_s"]),
                   surrogate_level_seconds=float(row["auto_picked_level_s"]),
                   iterations_left=_number(row.get("auto_iterations_left")),
                   time_left=_number(row.get("auto_time_left_s")),
                   random_levels_timed=None if row.get("auto_random_levels_timed") is None
                   else int(row["auto_random_levels_timed"]),
                   iterations_needed=_number(row.get("auto_iterations_needed")))

    def state_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)

    @classmethod
    def from_state_dict(cls, state: Mapping[str, Any] | None) -> "SearchChoice | None":
        return None if state is None else cls(**state)


def _number(value: Any) -> float | None:
    return None if value is None else float(value)


def random_level_seconds(history: Sequence[Mapping[str, float]]) -> float:
    """Wall seconds per level of the random first iteration's evaluation (``history[0]``)."""
    first = history[0]
    return first.get("time_evaluate", 0.0) / max(first.get("evaluated_this_iteration", 0.0), 1.0)


def probe_allowance(history: Sequence[Mapping[str, float]], *, surrogate_seconds: float, picks: int,
                    probed: int) -> float:
    """Seconds the probe's ``probed`` picks may take before a pick's projected cost is past the break-even (the
    probe is then stopped: at least one pick is evaluated whatever this is)."""
    per_pick = BREAK_EVEN_COST_RATIO * random_level_seconds(history) - surrogate_seconds / max(picks, 1)
    return max(per_pick, 0.0) * probed


def choose_by_time_left(*, random_seconds: float, time_left: float, proposal_seconds: float, picks: int,
                        evals_left: int, direct_variant: str) -> SearchChoice:
    """The choice right after the random iteration, with a time budget: the direct search if fewer than
    :data:`MIN_SURROGATE_ITERATIONS` surrogate iterations fit in ``time_left``, else DSAGE for now (``direct`` False:
    the probe decides later).

    Args:
        random_seconds: Wall seconds per level of the random iteration (:func:`random_level_seconds`).
        time_left: Wall seconds of the time budget left.
        proposal_seconds: The surrogate's first proposal, projected
            (:meth:`~dsage_ray.core.proposers.SurrogateAssisted.projected_proposal_seconds`).
        picks: Levels a surrogate iteration evaluates (within the evaluation budget).
        evals_left: Evaluations of the budget left after the random iteration: where fewer than
            :data:`MIN_SURROGATE_ITERATIONS` iterations spend them, DSAGE needs only those.
        direct_variant: The domain's direct search.
    """
    needed = float(min(MIN_SURROGATE_ITERATIONS, math.ceil(max(evals_left, 1) / max(picks, 1))))
    per_pick = proposal_seconds / max(picks, 1) + random_seconds
    iterations = time_left / (per_pick * max(picks, 1)) if per_pick > 0 else math.inf
    ratio = per_pick / random_seconds if random_seconds > 0 else math.inf
    return SearchChoice(direct=iterations < needed, variant=direct_variant, cost_ratio=ratio,
                        random_level_seconds=random_seconds, surrogate_level_seconds=per_pick,
                        iterations_left=iterations, time_left=time_left, iterations_needed=needed)


def choose_during_random(*, seconds: float, timed: int, random_levels: int, time_left: float, picks: int,
                         evals_left: int, direct_variant: str) -> SearchChoice:
    """The choice after the random iteration's first ``timed`` levels, with a time budget: the direct search if the
    rest, at their seconds, would leave room for fewer than :data:`MIN_SURROGATE_ITERATIONS` surrogate iterations
    even at no surrogate cost (each its picks at a random level's seconds), else DSAGE for now (the look after the
    random iteration, with the surrogate's projected proposal, comes next).

    Args:
        seconds: Wall seconds the ``timed`` levels took.
        timed: Random levels evaluated so far.
        random_levels: Levels of the whole random iteration (within the evaluation budget).
        time_left: Wall seconds of the time budget left now.
        picks: Levels a surrogate iteration evaluates (within the evaluation budget).
        evals_left: Evaluations of the budget left after the random iteration (:func:`choose_by_time_left`).
        direct_variant: The domain's direct search.
    """
    per_level = seconds / max(timed, 1)
    after_random = time_left - per_level * (random_levels - timed)
    choice = choose_by_time_left(random_seconds=per_level, time_left=after_random, proposal_seconds=0.0, picks=picks,
                                 evals_left=evals_left, direct_variant=direct_variant)
    return dataclasses.replace(choice, random_levels_timed=timed)


def choose_search(history: Sequence[Mapping[str, float]], *, surrogate_seconds: float, picks: int,
                  probe_seconds: float, probed: int, direct_variant: str,
                  before: SearchChoice | None = None) -> SearchChoice:
    """The choice once the surrogate's first picks are probed: a pick's projected cost against a random level's.

    Args:
        history: The run's metrics rows, oldest first; the first is the random iteration.
        surrogate_seconds: Seconds the first proposal spent training, exploiting and selecting.
        picks: Levels it proposed (within the budget).
        probe_seconds: Seconds the evaluation of the first ``probed`` of them took.
        probed: Picks evaluated for the choice (:data:`~dsage_ray.core.auto_proposer.PROBE_PICKS`, fewer where
            fewer were proposed).
        direct_variant: The domain's direct search.
        before: The time budget's look after the random iteration (:func:`choose_by_time_left`), which kept DSAGE:
            its numbers are carried into the choice (None: no time budget).
    """
    random_seconds = random_level_seconds(history)
    per_pick = surrogate_seconds / max(picks, 1) + probe_seconds / max(probed, 1)
    ratio = per_pick / random_seconds if random_seconds > 0 else float("inf")
    return SearchChoice(direct=ratio > BREAK_EVEN_COST_RATIO, variant=direct_variant, cost_ratio=ratio,
                        random_level_seconds=random_seconds, surrogate_level_seconds=per_pick,
                        iterations_left=None if before is None else before.iterations_left,
                        time_left=None if before is None else before.time_left,
                        iterations_needed=None if before is None else before.iterations_needed)


#: Keys that add to or filter a surrogate's picks: off in the direct search unless its variant sets them (an audit
#: gives DSAGE elite mutants; a direct search mutates its elites already).
_PICKS_ONLY = {"selection.elite_mutants": 0, "selection.screen_episodes": 0, "selection.screen_gain": False}


def direct_variant(config: RunConfig) -> str:
    """The variant ``search = "auto"`` may continue with: the domain's ``direct_search``."""
    return get_domain(config.domain).direct_search


def direct_config(config: RunConfig) -> RunConfig:
    """``config`` with the domain's direct search's keys over it: what the run continues with.

    Everything else (budget, time budget, seed, the domain's section) stays the run's, but the keys that add to a
    surrogate's picks (elite mutants, the screen), which the variant sets where it takes them.
    """
    name = direct_variant(config)
    return config.replace(**{**_PICKS_ONLY, **variants(config.domain)[name]}, variant=name, search="fixed")
