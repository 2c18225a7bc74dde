"""The Maze domain's registration: its config section, presets, variants and audit defaults.

Named by the ``maze`` entry point of the ``dsage_ray.domains`` group (pyproject.toml). Imports
nothing heavy: the domain itself (MiniGrid, numba, the agents) loads only when a domain is built.
"""

from __future__ import annotations

import dataclasses
from typing import Any, Callable, ClassVar, Literal

from dsage_ray.domains.registry import AgentKinds, AuditSpec, DomainSpec, ReportField, domain_key

#: Keys of :data:`dsage_ray.domains.maze.measures.OBJECTIVES`.
MazeObjective = Literal["validity", "failure_rate", "regret", "regression"]


@dataclasses.dataclass
class MazeConfig:
    """The Maze domain (SPEC: the Maze)."""

    #: Work counts its domain reports per evaluation (``work_counts``).
    work_names: ClassVar[tuple[str, ...]] = ("steps",)
    agent: str = domain_key("builtin:wall_follower",
                            note="the agent spec audited (dcd:, rllib:, torchscript:, builtin:...)")
    episodes: int = domain_key(50, note="episodes per evaluation, played side by side")
    height: int = domain_key(16, note="rows of the interior wall bitmap")
    width: int = domain_key(16, note="columns of the interior wall bitmap")
    see_through_walls: bool = domain_key(True, note="the agent's view passes walls, as ACCEL was trained")
    #: ``validity`` (paper), ``failure_rate``, ``regret`` or ``regression`` (audits).
    objective: MazeObjective = domain_key("validity",
                                          note="validity (the paper), failure_rate, regret or regression (audits)")
    #: Reference agent spec of the ``regression`` objective (empty: none), run on the same seeds.
    reference: str = domain_key("", note="the regression objective's reference agent, played on the same seeds")
    measures: tuple[str, ...] = domain_key(("num_walls", "mean_path_length"), note="the archive's two measures")
    #: Cells per measure; ``0`` means "one cell per integer value" (the paper's 256×162 uses 256 and 162).
    archive_dims: tuple[int, ...] = domain_key((256, 162), note="cells per measure; 0: one per integer value")
    #: ``()`` means the natural range of each measure.
    measure_ranges: tuple[tuple[float, float], ...] = domain_key((),
                                                                 note="each measure's range; empty: its natural range")
    #: Give the surrogate two more input channels: cells reachable from the start and cells on a
    #: shortest start-goal path (:data:`dsage_ray.domains.maze.encoding.PATH_CHANNELS`). Not in the
    #: paper, whose 5-channel one-hot input is the default.
    path_channels: bool = domain_key(False,
                                     note="2 more surrogate inputs: reachable cells, a shortest path (not the paper's)")

    def validate(self, need: Callable[[bool, str, str], None]) -> None:
        """Checks the Maze keys; ``need(condition, key, why)`` reports the first that fails."""
        need(self.episodes >= 1, "episodes", "must be positive")
        need(self.height >= 2 and self.width >= 2, "height", "maze must be at least 2x2")
        need(bool(self.reference) == (self.objective == "regression"), "reference",
             "the 'regression' objective needs a reference agent spec, and only it uses one")


#: ``paper`` reproduces the paper's numbers; ``cpu`` finishes well under an hour on 2 cores; ``demo``
#: is the few-minute run of ``make run``; ``tiny`` is for tests and smoke runs.
PRESETS: dict[str, dict[str, Any]] = {
    # The paper held no levels out; ``--set experimental.holdout_levels=100`` adds 0.1% to its budget.
    "paper": {},
    # CPU presets scale the paper's loop down (SPEC, the surrogate: one paper inner loop is ~20 minutes of
    # surrogate predictions on 2 cores). A shorter inner loop fills a smaller surrogate archive,
    # so blocks are smaller to keep a useful number of picks per outer iteration, and a smaller
    # batch gives the surrogate enough Adam steps on the few samples it has early on.
    # 4,000 evaluations: the length at which the design below was measured (about 11 CPU minutes a search);
    # its lead over MAP-Elites at equal CPU time grows with the run (1.06× at 2,000 evaluations, fresh seeds 60-62,
    # docs/DECISIONS.md).
    "cpu": {
        "budget": 4_000,
        "n_rand": 100,
        "maze.episodes": 50,
        "surrogate.epochs": 10,
        "surrogate.batch_size": 16,
        "surrogate.train_window": 1_000,
        "qd.exploit_iterations": 300,
        "selection.count": 100,
        # The best equal-time design measured (docs/DECISIONS.md; fresh seeds 48-50: 1.31 ± 0.03×
        # MAP-Elites at equal CPU time, 1.59× per evaluation; as this preset on fresh seeds 60-62, less at equal
        # time, the same per evaluation): a 16-channel network (the surrogate's share of the
        # run from about 50% to 17%), a one-episode screen of each pick and of more candidates, ranked by the QD-score
        # each is expected to add per expected cost (the Maze's evaluation_cost), and 2 × 3 blocks (more picks per
        # outer iteration, so the surrogate trains and exploits less often per evaluation). No held-out levels: they
        # are a diagnostic (``--set experimental.holdout_levels=100`` adds 5% evaluations to score the surrogate).
        "surrogate.channels": 16,
        "selection.screen_episodes": 1,
        "selection.screen_gain": True,
        "selection.block": (2, 3),
        # Measured on a seed-0 ACCEL run's own data (benchmarks/bench_surrogate_training.py, README):
        # held-out Spearman ρ of the path length 0.18-0.37 with these channels vs 0.03-0.06 without.
        # More epochs, batch 64, a 20,000 window, early stopping and range-scaled targets did not help.
        "maze.path_channels": True,
        # The path length is the sum of the agent's occupancy grid. Predicted as the sum of the predicted
        # occupancy, 3 seeds of ACCEL runs ended at QD-score 1,597 ± 17.5 against 1,423.7 ± 24.7 with a
        # head per measure (README, "Does the surrogate predict the agent?").
        "surrogate.occupancy_sum_measure": "mean_path_length",
        # Blended half-and-half with a uniform random walker's hitting time (surrogate.prior_measure): on
        # fresh seeds 11-17 of ACCEL the selected-batch error fell by 30% on every seed; the QD-score was
        # level on the seeds run after this choice (docs/results/surrogate_accuracy, "A random walker").
        "surrogate.prior_measure": "mean_path_length",
    },
    "demo": {
        "budget": 500,
        "n_rand": 100,
        "maze.episodes": 50,
        "surrogate.epochs": 20,
        "surrogate.batch_size": 16,
        "surrogate.train_window": 1_000,
        "qd.exploit_iterations": 100,
        "selection.block": (4, 3),
        "selection.count": 50,
    },
    "tiny": {
        "budget": 150,
        "n_rand": 50,
        "maze.episodes": 5,
        "surrogate.epochs": 5,
        "surrogate.batch_size": 16,
        "qd.exploit_iterations": 10,
        "selection.block": (2, 2),
        "selection.count": 20,
    },
}

#: The paper's Maze QD baseline beside the DSAGE variants and DR (common to every domain).
VARIANTS: dict[str, dict[str, Any]] = {
    # The paper's MAP-Elites, unscreened whatever the preset screens (``--set selection.screen_episodes=1
    # selection.screen_gain=true`` gives it the ranked screen: the strongest baseline measured, docs/DECISIONS.md).
    "map_elites": {"surrogate.kind": "none", "qd.emitter": "map_elites", "qd.num_emitters": 5, "qd.batch_size": 30,
                   "selection.screen_episodes": 0, "selection.screen_gain": False},
}

#: The Maze numbers of a collection entry the audit report shows (``MazeDomain.entry_fields``).
COLUMNS = (
    ReportField(key="num_walls"),
    ReportField(key="optimal_path_length"),
    ReportField(key="mean_path_length", mean="mean path length",
                # A failed episode counts the whole step limit: the report says which number that is.
                tooltip="mean steps per episode; a failed episode counts as the whole step limit, {max_steps} steps, "
                        "so {max_steps} means the agent never reached the goal"),
    ReportField(key="explored_fraction"),
    ReportField(key="repeated_visits"),
)


DOMAIN = DomainSpec(
    name="maze",
    config=MazeConfig,
    domain="dsage_ray.domains.maze.domain:MazeDomain",
    presets=PRESETS,
    variants=VARIANTS,
    # search = "auto" continues with MAP-Elites, the paper's Maze baseline (DSAGE leads it at equal CPU time: auto
    # keeps DSAGE here).
    direct_search="map_elites",
    # MazeDomain.screen: the agent on many levels at once for a few episodes (selection.screen_episodes).
    screenable=True,
    # The paper's Table 2 rows (``dsage_rsample`` is the appendix ablation).
    comparison=("dsage", "dsage_only_anc", "dsage_only_down", "dsage_basic", "map_elites", "dr"),
    audit=AuditSpec(
        # ``regression`` also needs a reference agent.
        objectives=("failure_rate", "regret", "regression"),
        # What the level looks like, not what the agent did.
        measures=("num_walls", "optimal_path_length"),
        # The PPO agent shipped with the package.
        default_agent="rllib:ppo_maze",
        episodes_key="maze.episodes",
        columns=COLUMNS,
        settings=(ReportField(key="max_steps", label="step limit", format="{} steps per episode"),),
        # Mutants of the never-solved mazes found so far, beside the surrogate's picks: at equal search time
        # they multiplied the never-solved mazes an audit finds (docs/DECISIONS.md).
        surrogate_keys={"selection.elite_mutants": 150},
        auto_keeps_dsage=("its picks cost 4.5-5.3x a random maze (a maze the agent never solves runs to the step "
                          "limit), past auto's break-even, yet in the same 7 minutes of search DSAGE's audit found "
                          "545 failing cells to the 181 of auto's switch to MAP-Elites (docs/DECISIONS.md)"),
        nominal="an open room",
        measures_note="the paper's: num_walls,mean_path_length",
        examples=(
            "dsage-ray audit                                         # a demo: the shipped PPO agent, --preset demo",
            "dsage-ray audit --agent dcd:path/to/agent.tar --out tb_logs/audit_mine     # your agent (cpu preset)",
            "dsage-ray audit --agent builtin:random --preset tiny --local               # a smoke test, no Ray",
            "dsage-ray audit --agent rllib:path/to/new --reference rllib:path/to/old    # where new is worse than old",
            "dsage-ray compare --agent rllib:ppo_maze --agent builtin:wall_follower --collection "
            "tb_logs/audit_mine/collection",
            "dsage-ray audit --agent dcd:accel --out tb_logs/audit_accel --resume        # after Ctrl+C",
        ),
    ),
    # Policies on MiniGrid's observation: the Maze's own kinds (dsage_ray/domains/maze/agents/: the wall follower,
    # DCD/ACCEL, and its rllib and torchscript conventions), shipped agents and plug-in kinds.
    agents=AgentKinds(
        forms={"builtin": "builtin:NAME", "dcd": "dcd:PATH", "rllib": "rllib:PATH", "torchscript": "torchscript:PATH"},
        loaders={"builtin": "dsage_ray.domains.maze.agents.builtin:load_builtin_agent",
                 "dcd": "dsage_ray.domains.maze.agents.dcd:load_dcd_agent",
                 "rllib": "dsage_ray.domains.maze.agents.rllib:load_rllib_agent",
                 "torchscript": "dsage_ray.domains.maze.agents.torchscript:load_torchscript_agent"},
        plugins=True,
    ),
    cli="dsage_ray.domains.maze.cli",
)
