"""GridPath's registration: its config section, presets, variants, agents and audit (imports nothing heavy)."""

from __future__ import annotations

import dataclasses
from typing import Callable, Literal

from dsage_ray.domains import AgentKinds, AuditSpec, DomainSpec, ReportField


@dataclasses.dataclass
class GridPathConfig:
    """The ``[gridpath]`` section of a run config."""

    #: Side of the square grid.
    size: int = 8
    #: Wall probability of the random levels (DR's and DSAGE's first outer iteration).
    density: float = 0.3
    #: ``bfs`` (walks the shortest path) or ``bfs:MOVES`` (gives up after MOVES moves).
    agent: str = "bfs"
    #: ``detour`` (the path length relative to the grid) or ``failure`` (audits: 1 when the agent does not
    #: reach a reachable goal).
    objective: Literal["detour", "failure"] = "detour"
    #: The agent is deterministic: one episode says all (the audit records it per level).
    episodes: int = 1
    measures: tuple[str, ...] = ("num_walls", "reachable")
    archive_dims: tuple[int, ...] = (16, 16)
    #: ``()``: each measure's natural range, [0, size²].
    measure_ranges: tuple[tuple[float, float], ...] = ()

    def validate(self, need: Callable[[bool, str, str], None]) -> None:
        need(self.size >= 2, "size", "must be at least 2")
        need(0.0 <= self.density <= 1.0, "density", "must be in [0, 1]")
        need(self.episodes >= 1, "episodes", "must be positive")


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
    # The agent specs `--agent` takes (dsage-ray audit, dsage-ray compare); others are refused by name.
    agents=AgentKinds(forms={"bfs": "bfs[:MOVES]"}),
    # `dsage-ray audit --domain gridpath`: levels whose goal is reachable but the agent gives up first.
    audit=AuditSpec(
        objectives=("failure",),
        measures=("num_walls", "reachable"),
        default_agent="bfs:20",
        episodes_key="gridpath.episodes",
        # The report's column beside the measures; `mean` also makes `dsage-ray compare` show it per agent.
        columns=(ReportField(key="path_length", label="path length", mean="mean path length",
                             tooltip="cells on the shortest path from the top-left corner to the bottom-right one "
                                     "of this {size}x{size} grid, both included"),),
        settings=(ReportField(key="size", label="grid", format="{0}x{0} cells"),),
    ),
    cli="dsage_ray_gridpath.cli",
)
