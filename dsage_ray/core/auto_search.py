"""``search = "auto"``: keep DSAGE, or continue with the domain's direct QD search, by what the surrogate costs.

DSAGE buys better levels per evaluation with surrogate time: training, the inner loop and the selection. Where a
real evaluation is cheap next to that time, a direct QD search (MAP-Elites, CMA-ME, a falsifier) evaluates many
more levels in the same time and finds more. The benchmarks put the break-even on the cost of a level:

* Maze (ACCEL or PPO, the ``cpu`` preset): a level DSAGE picked cost 1.3-1.7× a random level, surrogate
  included, and DSAGE led MAP-Elites at equal CPU time (1.15×, docs/results/equal_compute §19);
* CartPole: about 1.9×, and DSAGE was level with the best falsifier at equal CPU time (docs/results/gym_audit);
* Mario (A*): more than 10×, and CMA-ME found twice DSAGE's QD-score at equal CPU time (equal_compute §6, §18).

So after the first outer iteration that used the surrogate, :func:`choose_search` compares that iteration's
seconds per evaluated level (every phase: training, inner loop, selection, evaluation) with the first, random
iteration's seconds per level, and the run continues with the domain's direct search
(:attr:`dsage_ray.domains.registry.DomainSpec.direct_search`) on the same archive when the ratio exceeds
:data:`BREAK_EVEN_COST_RATIO`. The seconds are wall seconds, so a run with more simulators (a Ray pool: each level
cheaper in wall time, the surrogate not) leans to the direct search, as it should at equal wall time.

The choice reads only the run's metrics rows, is made once, and is part of the run's state.
"""

from __future__ import annotations

import dataclasses
from typing import Any, Mapping, Sequence

from dsage_ray.config import RunConfig, variants
from dsage_ray.domains.registry import get_domain

#: Above this ratio (seconds per level DSAGE picked, surrogate included / seconds per random level) the run
#: continues with the direct search. Between the ratios where DSAGE won or was level at equal CPU time (Maze
#: 1.3-1.7, CartPole 1.9) and where it lost by half (Mario, above 10).
BREAK_EVEN_COST_RATIO = 3.0

#: The phases of an outer iteration that run in the driver and count towards a level's cost (``time_<phase>``).
_COUNTED_PHASES = ("train", "exploit", "select", "evaluate")


@dataclasses.dataclass(frozen=True)
class SearchChoice:
    """What ``search = "auto"`` chose, and why.

    Attributes:
        direct: The run continues with :attr:`variant` (the domain's direct search); else it stays DSAGE.
        variant: The direct search's variant name (whether or not it was chosen).
        cost_ratio: Seconds per level of the first surrogate iteration / of the random first iteration.
        random_level_seconds: Wall seconds per level of the random first iteration (its evaluation).
        surrogate_level_seconds: Wall seconds per level of the first surrogate iteration, every phase counted.
        outer_iteration: The outer iterations done when the choice was made.
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
        numbers = (f"a level DSAGE picked cost {self.surrogate_level_seconds:.3g} s with the surrogate's time, "
                   f"{self.cost_ratio:.2f}× a random level's {self.random_level_seconds:.3g} s; "
                   f"break-even {BREAK_EVEN_COST_RATIO:g}×")
        if self.direct:
            return f"search auto: continuing with {self.variant} on the same archive ({numbers})"
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


def level_seconds(row: Mapping[str, float]) -> float:
    """Wall seconds per evaluated level of one outer iteration's metrics row (held-out levels not counted)."""
    seconds = sum(row.get(f"time_{phase}", 0.0) for phase in _COUNTED_PHASES)
    return seconds / max(row.get("evaluated_this_iteration", 0.0), 1.0)


def choose_search(history: Sequence[Mapping[str, float]], *, direct_variant: str) -> SearchChoice | None:
    """The choice, once the run has a random iteration and a surrogate iteration behind it (else None).

    Args:
        history: The run's metrics rows, oldest first.
        direct_variant: The domain's direct search.
    """
    surrogate_rows = [i for i, row in enumerate(history) if row.get("time_exploit", 0.0) > 0]
    if not surrogate_rows or surrogate_rows[0] == 0:
        return None  # a warm-started run exploits from its first iteration: no random level to compare with
    random_row, surrogate_row = history[0], history[surrogate_rows[0]]
    random_seconds = random_row.get("time_evaluate", 0.0) / max(random_row.get("evaluated_this_iteration", 0.0), 1.0)
    picked_seconds = level_seconds(surrogate_row)
    ratio = picked_seconds / random_seconds if random_seconds > 0 else float("inf")
    return SearchChoice(direct=ratio > BREAK_EVEN_COST_RATIO, variant=direct_variant, cost_ratio=ratio,
                        random_level_seconds=random_seconds, surrogate_level_seconds=picked_seconds,
                        outer_iteration=surrogate_rows[0] + 1)


def direct_variant(config: RunConfig) -> str:
    """The variant ``search = "auto"`` may continue with: the domain's ``direct_search``."""
    return get_domain(config.domain).direct_search


def direct_config(config: RunConfig) -> RunConfig:
    """``config`` with the domain's direct search's keys over it: what the run continues with.

    Everything else (budget, time budget, seed, the domain's section) stays the run's.
    """
    name = direct_variant(config)
    return config.replace(**variants(config.domain)[name], variant=name, search="fixed")
