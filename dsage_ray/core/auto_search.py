"""``search = "auto"``: keep DSAGE, or continue with the domain's direct QD search, by what the surrogate costs.

DSAGE buys better levels per evaluation with surrogate time: training, the inner loop and the selection. Where a
real evaluation is cheap next to that time, a direct QD search (MAP-Elites, CMA-ME, a falsifier) evaluates many
more levels in the same time and finds more. What decides is the surrogate's seconds per level it picks, next to
the seconds a level's evaluation takes. The benchmarks put the break-even there:

* Maze (the ``cpu`` preset, ACCEL or PPO): the first picks cost 1.8-1.9× a random level's evaluation, surrogate
  time added, and DSAGE led MAP-Elites at equal CPU time (1.15×, docs/results/equal_compute §19);
* CartPole (the ``demo`` audit): about 2.2×, and DSAGE was level with the best falsifier at equal CPU time
  (docs/results/gym_audit);
* Mario (A*, the ``cpu`` preset): CMA-ME found twice DSAGE's QD-score at equal CPU time (equal_compute §6, §18),
  and the ratio is measured in §21.

So once the random first iteration is evaluated and the surrogate has made its first picks, and before they are
evaluated, :func:`choose_search` sets ``1 + (surrogate seconds per pick) / (seconds per random level)`` against
:data:`BREAK_EVEN_COST_RATIO`. Above it the picks are dropped unevaluated and the run continues with the domain's
direct search (:attr:`dsage_ray.domains.registry.DomainSpec.direct_search`) on the same archive, so a domain where
the surrogate does not pay loses only that one surrogate iteration. The seconds are wall seconds, so a run with
more simulators (a Ray pool: each level cheaper in wall time, the surrogate not) leans to the direct search, as it
should at equal wall time. Like a time budget, the choice depends on the machine: an ``auto`` run is reproducible
given its choice (it is part of the run's state and of its metrics), not across machines.
"""

from __future__ import annotations

import dataclasses
from typing import Any, Mapping, Sequence

from dsage_ray.config import RunConfig, variants
from dsage_ray.domains.registry import get_domain

#: Above this ratio (1 + surrogate seconds per pick / seconds per random level) the run continues with the direct
#: search. Above the ratios where DSAGE won or was level at equal CPU time (Maze 1.8-1.9, CartPole 2.2), below
#: Mario's, where it lost by half.
BREAK_EVEN_COST_RATIO = 3.0

#: The phases of a surrogate proposal that its cost counts (``Proposal.times``; held-out levels are not the search's).
SURROGATE_PHASES = ("train", "exploit", "select")


@dataclasses.dataclass(frozen=True)
class SearchChoice:
    """What ``search = "auto"`` chose, and why.

    Attributes:
        direct: The run continues with :attr:`variant` (the domain's direct search); else it stays DSAGE.
        variant: The direct search's variant name (whether or not it was chosen).
        cost_ratio: ``1 + surrogate_level_seconds / random_level_seconds``: what a picked level costs, surrogate
            included, over what a random level costs, were both as quick to play.
        random_level_seconds: Wall seconds per level of the random first iteration's evaluation.
        surrogate_level_seconds: Wall seconds of the surrogate's first proposal (training, inner loop, selection)
            per level it picked.
        outer_iteration: The outer iteration the choice was made in (before its levels were evaluated).
    """

    direct: bool
    variant: str
    cost_ratio: float
    random_level_seconds: float
    surrogate_level_seconds: float
    outer_iteration: int

    @property
    def reason(self) -> str:
        """One line for the log: the choice and the numbers it was made on."""
        numbers = (f"the surrogate spent {self.surrogate_level_seconds:.3g} s per level it picked, a random level's "
                   f"evaluation {self.random_level_seconds:.3g} s: a pick costs {self.cost_ratio:.2f}× a random level; "
                   f"break-even {BREAK_EVEN_COST_RATIO:g}×")
        if self.direct:
            return f"search auto: continuing with {self.variant} on the same archive, picks dropped ({numbers})"
        return f"search auto: staying with DSAGE ({numbers})"

    def metrics(self) -> dict[str, float]:
        """The choice as metrics columns of the row it was made after (TensorBoard, ``metrics.json``, Tune)."""
        return {"auto_direct": float(self.direct), "auto_cost_ratio": self.cost_ratio,
                "auto_random_level_s": self.random_level_seconds, "auto_picked_level_s": self.surrogate_level_seconds}

    @classmethod
    def from_metrics(cls, row: Mapping[str, Any], *, variant: str) -> "SearchChoice | None":
        """The choice a metrics row (a Tune result) carries, None where it has none: its :meth:`metrics` columns."""
        if "auto_cost_ratio" not in row:
            return None
        return cls(direct=bool(row["auto_direct"]), variant=variant, cost_ratio=float(row["auto_cost_ratio"]),
                   random_level_seconds=float(row["auto_random_level_s"]),
                   surrogate_level_seconds=float(row["auto_picked_level_s"]),
                   outer_iteration=int(row.get("outer_iteration", 0)))

    def state_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)

    @classmethod
    def from_state_dict(cls, state: Mapping[str, Any] | None) -> "SearchChoice | None":
        return None if state is None else cls(**state)


def choose_search(history: Sequence[Mapping[str, float]], *, surrogate_seconds: float, picks: int,
                  direct_variant: str) -> SearchChoice:
    """The choice, made when the surrogate's first picks are ready and before they are evaluated.

    Args:
        history: The run's metrics rows, oldest first; the first is the random iteration.
        surrogate_seconds: Seconds the first proposal spent in :data:`SURROGATE_PHASES`.
        picks: Levels it proposes.
        direct_variant: The domain's direct search.
    """
    first = history[0]
    random_seconds = first.get("time_evaluate", 0.0) / max(first.get("evaluated_this_iteration", 0.0), 1.0)
    per_pick = surrogate_seconds / max(picks, 1)
    ratio = 1.0 + per_pick / random_seconds if random_seconds > 0 else float("inf")
    return SearchChoice(direct=ratio > BREAK_EVEN_COST_RATIO, variant=direct_variant, cost_ratio=ratio,
                        random_level_seconds=random_seconds, surrogate_level_seconds=per_pick,
                        outer_iteration=len(history))


def direct_variant(config: RunConfig) -> str:
    """The variant ``search = "auto"`` may continue with: the domain's ``direct_search``."""
    return get_domain(config.domain).direct_search


def direct_config(config: RunConfig) -> RunConfig:
    """``config`` with the domain's direct search's keys over it: what the run continues with.

    Everything else (budget, time budget, seed, the domain's section) stays the run's.
    """
    name = direct_variant(config)
    return config.replace(**variants(config.domain)[name], variant=name, search="fixed")
