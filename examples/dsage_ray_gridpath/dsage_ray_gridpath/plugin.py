"""GridPath's registration: its config section, presets and variants (imports nothing heavy)."""

from __future__ import annotations

import dataclasses
from typing import Callable

from dsage_ray.domains import DomainSpec


@dataclasses.dataclass
class GridPathConfig:
    """The ``[gridpath]`` section of a run config."""

    #: Side of the square grid.
    size: int = 8
    #: Wall probability of the random levels (DR's and DSAGE's first outer iteration).
    density: float = 0.3
    measures: tuple[str, ...] = ("num_walls", "reachable")
    archive_dims: tuple[int, ...] = (16, 16)
    #: ``()``: each measure's natural range, [0, size²].
    measure_ranges: tuple[tuple[float, float], ...] = ()

    def validate(self, need: Callable[[bool, str, str], None]) -> None:
        need(self.size >= 2, "size", "must be at least 2")
        need(0.0 <= self.density <= 1.0, "density", "must be in [0, 1]")


DOMAIN = DomainSpec(
    name="gridpath",
    config=GridPathConfig,
    domain="dsage_ray_gridpath.domain:GridPathDomain",
    presets={
        "paper": {},  # the default preset: dsage_ray's full-size defaults
        # Seconds: for tests and smoke runs.
        "tiny": {"budget": 40, "n_rand": 20, "surrogate.epochs": 2, "surrogate.batch_size": 16,
                 "qd.num_emitters": 2, "qd.batch_size": 10, "qd.exploit_iterations": 5,
                 "selection.block": (2, 2), "selection.count": 20},
    },
    variants={"map_elites": {"surrogate.kind": "none", "qd.emitter": "map_elites"}},
    comparison=("dsage", "map_elites"),
)
