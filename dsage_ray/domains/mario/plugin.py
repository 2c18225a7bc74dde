"""The Mario domain's registration: its config section, presets, variants and audit defaults.

Named by the ``mario`` entry point of the ``dsage_ray.domains`` group (pyproject.toml). Imports
neither torch nor JPype: the domain, the generator and the JVM load only when a domain is built.
"""

from __future__ import annotations

import dataclasses
from typing import Any, Callable, ClassVar, Literal

from dsage_ray.domains.registry import AgentKinds, AuditSpec, DomainSpec, ReportField, domain_key

#: Mario's objectives: the A* agent's completion, or ``1 - completion`` (audits).
MarioObjective = Literal["completion", "incompletion"]


@dataclasses.dataclass
class MarioConfig:
    """The Mario domain (SPEC: Mario)."""

    #: Work counts its domain reports per evaluation (``work_counts``).
    work_names: ClassVar[tuple[str, ...]] = ("search_iterations", "ticks")
    runs: int = domain_key(5, note="episodes per level (1 when A* is deterministic)")
    timer: int = domain_key(20, note="game time in seconds (20 = 666 ticks)")
    astar_iterations: int = domain_key(1000,
                                       note="A* iterations per tick (deterministic); 0: the stock 40 ms timer")
    episode_timeout_s: float = domain_key(60.0, note="wall-clock seconds an episode may take")
    generator: str = domain_key("builtin", note="builtin (the shipped GAN) or a weights file")
    #: Standard deviation of the random latents (DR's and DSAGE's ``n_rand`` initial ones); the
    #: authors drew them from N(0, 0.2²).
    latent_sigma: float = domain_key(0.2,
                                     note="std of the random latents (DR and DSAGE's first levels); the paper's 0.2")
    #: ``completion`` (paper) or ``incompletion`` (1 − completion, audits).
    objective: MarioObjective = domain_key("completion", note="completion (the paper) or incompletion (audits)")
    measures: tuple[str, ...] = domain_key(("sky_tiles", "mean_jumps"), note="the archive's two measures")
    archive_dims: tuple[int, ...] = domain_key((150, 100), note="cells per measure")
    measure_ranges: tuple[tuple[float, float], ...] = domain_key(((0.0, 150.0), (0.0, 100.0)),
                                                                 note="each measure's range")

    def validate(self, need: Callable[[bool, str, str], None]) -> None:
        """Checks the Mario keys; ``need(condition, key, why)`` reports the first that fails."""
        need(self.runs >= 1, "runs", "must be positive")
        need(self.timer >= 1, "timer", "must be positive")
        need(self.astar_iterations >= 0, "astar_iterations", "must be >= 0 (0: stock wall-clock timer)")
        need(self.latent_sigma > 0, "latent_sigma", "must be positive")


#: ``paper`` reproduces the paper's numbers; ``cpu`` is a CPU-sized run; ``tiny`` is for tests.
PRESETS: dict[str, dict[str, Any]] = {
    # The paper's Mario runs spend 10,000 evaluations (its Table 2: Basic never reaches the
    # target within 10,000) and draw random latents from N(0, 0.2²).
    "paper": {
        "budget": 10_000,
        "mario.latent_sigma": 0.2,
        "n_rand": 100,
        "qd.emitter": "cma_me",
        "qd.num_emitters": 1,
        "qd.batch_size": 30,
        "selection.block": (5, 5),
        "selection.count": 250,
        "surrogate.train_window": 20_000,
    },
    # The Mario surrogate sees 64×64 inputs: one training step is ~16× a Maze step, so the
    # CPU preset trains fewer epochs on a shorter window and uses both cores for it
    # (torch_threads; its phases never overlap the simulators'). Runs cost nothing extra:
    # the iteration-count A* timer makes all 5 runs one episode. Random latents at σ = 1, the
    # shipped generator's training prior: at the paper's 0.2 it draws near-empty skies (30 levels
    # reach 5 archive cells vs 26 at σ = 1; benchmarks/bench_latent_sigma.py).
    "cpu": {
        "budget": 500,
        "n_rand": 100,
        "mario.latent_sigma": 1.0,
        "qd.emitter": "cma_me",
        "qd.num_emitters": 1,
        "surrogate.epochs": 10,
        "surrogate.batch_size": 16,
        "surrogate.train_window": 300,
        "qd.exploit_iterations": 100,
        "selection.block": (5, 5),
        "selection.count": 100,
        "torch_threads": 2,
    },
    "tiny": {
        "budget": 12,
        "n_rand": 6,
        "qd.emitter": "cma_me",
        "qd.num_emitters": 1,
        "qd.batch_size": 4,
        "mario.runs": 1,
        "mario.timer": 5,
        "mario.latent_sigma": 1.0,
        "surrogate.epochs": 2,
        "qd.exploit_iterations": 3,
        "selection.block": (30, 20),
        "selection.count": 6,
    },
}

#: The paper's Mario QD baseline beside the DSAGE variants and DR (common to every domain).
VARIANTS: dict[str, dict[str, Any]] = {
    "cma_me": {"surrogate.kind": "none", "qd.emitter": "cma_me", "qd.num_emitters": 5, "qd.batch_size": 30},
}


def actor_env() -> dict[str, str]:
    """A simulator actor's JVM needs signal chaining next to the faulthandler Ray workers enable."""
    from dsage_ray.domains.mario.simulator import signal_chaining_library

    chaining = signal_chaining_library()
    return {"LD_PRELOAD": chaining} if chaining else {}


DOMAIN = DomainSpec(
    name="mario",
    config=MarioConfig,
    domain="dsage_ray.domains.mario.domain:MarioDomain",
    presets=PRESETS,
    variants=VARIANTS,
    # search = "auto" continues with CMA-ME: twice DSAGE's QD-score at equal CPU time (docs/DECISIONS.md).
    direct_search="cma_me",
    # The paper's Table 2 rows (``dsage_rsample`` is the appendix ablation).
    comparison=("dsage", "dsage_only_anc", "dsage_only_down", "dsage_basic", "cma_me", "dr"),
    audit=AuditSpec(
        # 1 − completion.
        objectives=("incompletion",),
        # The paper's measures.
        measures=("sky_tiles", "mean_jumps"),
        default_agent="astar",
        episodes_key="mario.runs",
        columns=(
            ReportField(key="completion", mean="mean completion",
                        tooltip="mean share of the level Mario covered over the runs (1: reached the flag)"),
            ReportField(key="jumps", tooltip="mean jumps per run"),
            ReportField(key="kills", tooltip="mean enemies killed per run"),
            ReportField(key="sky_tiles", tooltip="non-empty tiles in the top 9 rows"),
        ),
        nominal="a flat level",
        episodes_word="runs",
        objective_notes={"incompletion": "1 - completion"},
        measures_note="the paper's",
        examples=("dsage-ray audit --domain mario --agent astar --preset tiny",
                  "dsage-ray compare --agent astar --agent astar:200 --collection tb_logs/audit_mario/collection"),
    ),
    # Robin Baumgarten's A* agent, the only one the simulator plays; ITERATIONS per tick (0: the 40 ms timer).
    agents=AgentKinds(forms={"astar": "astar[:ITERATIONS]"}),
    cli="dsage_ray.domains.mario.cli",
    actor_env=actor_env,
)
