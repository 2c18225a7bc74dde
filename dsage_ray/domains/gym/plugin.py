"""The gym domain's registration: any Gymnasium environment, re-parameterised per level (imports nothing heavy).

Named by the ``gym`` entry point of the ``dsage_ray.domains`` group (pyproject.toml). A level is one value per
parameter of a space (:mod:`dsage_ray.domains.gym.space`): a shipped one (``cartpole``, ``lunarlander``), a TOML
file, or ``--param`` strings on the command line.
"""

from __future__ import annotations

import dataclasses
from typing import Any, Callable, ClassVar, Literal

from dsage_ray.domains.registry import AgentKinds, AuditFlag, AuditSpec, DomainSpec, ReportField, domain_key

#: ``failure_rate``: the share of the level's episodes that fail the space's success test.
GymObjective = Literal["failure_rate"]


@dataclasses.dataclass
class GymConfig:
    """The ``[gym]`` section of a run config."""

    #: Work counts its domain reports per evaluation (``work_counts``: environment steps), which
    #: benchmarks may read.
    work_names: ClassVar[tuple[str, ...]] = ("steps",)

    #: A shipped space's name (``cartpole``, ``lunarlander``), a space file (TOML), or "" (``params`` only).
    space: str = domain_key("cartpole",
                            note="a shipped space (cartpole, lunarlander), a space file (TOML), or empty (params only)")
    #: The Gymnasium id; "" takes the space's ``[env] id``.
    env: str = domain_key("", note="the Gymnasium id; empty: the space's [env] id")
    #: ``--param`` strings over the space's parameters: ``NAME=LOW:HIGH`` (a gym.make keyword), ``attr.NAME=...``
    #: (an attribute of env.unwrapped after reset), ``reset.NAME=...`` (a reset option); ``LOW:HIGH:int``, ``A|B|C``.
    params: tuple[str, ...] = domain_key((),
                                         note="--param NAME=LOW:HIGH strings (gym.make; attr.NAME=..., reset.NAME=...)")
    #: ``--env-arg KEY=VALUE`` strings: fixed gym.make keywords over the space's ``[env] args``.
    env_args: tuple[str, ...] = domain_key((), note="--env-arg KEY=VALUE strings: fixed gym.make keywords")
    #: ``--space-set`` lines of a space file set over it (``success.return_at_least = 200``): anything a space
    #: file declares, so a one-off audit needs no file.
    space_set: tuple[str, ...] = domain_key((), note="--space-set lines set over the space file")
    #: The agent spec (a form of the registration's ``agents``; :mod:`dsage_ray.agents.kinds`).
    agent: str = domain_key("rllib:ppo_cartpole",
                            note="the agent spec audited (rllib:, torchscript:, sb3:, python:...)")
    objective: GymObjective = domain_key("failure_rate",
                                         note="failure_rate: the share of episodes failing the space's success test")
    episodes: int = domain_key(10, note="episodes per evaluation, played side by side")
    #: Archive measures, names of the space's measures; ``()``: the space's ``[audit] measures``.
    measures: tuple[str, ...] = domain_key((), note="the archive's measures; empty: the space's [audit] measures")
    #: Cells per measure; ``()``: each measure's ``cells``.
    archive_dims: tuple[int, ...] = domain_key((), note="cells per measure; empty: each measure's cells")
    #: ``()``: each measure's declared range.
    measure_ranges: tuple[tuple[float, float], ...] = domain_key((),
                                                                 note="each measure's range; empty: its declared range")

    def complete(self, run: Any, *, given: frozenset[str]) -> None:
        """Reads the space and fills what was left to it: the measures (its ``[audit] measures``, else its first two
        declared ones), their cells, one downsampling block size per measure, and, where the space declares a
        ``[fault]``, the search of :data:`FAULT_SEARCH` for each of its keys not in ``given``.

        Raises:
            SpaceError: A space that does not load, or a measure it does not declare.
        """
        from dsage_ray.domains.gym.space import load_space

        space = load_space(self)
        if not self.measures:
            declared = [name for name in space.measures if not name.startswith("param.")
                        and name not in ("terminated", "truncated")]
            self.measures = space.audit_measures or tuple((declared + [f"param.{p.name}" for p in space.params])[:2])
        for name in self.measures:
            space.measure(name)
        if not self.archive_dims:
            self.archive_dims = tuple(space.measures[name].cells for name in self.measures)
        if len(run.selection.block) != len(self.measures):
            run.selection.block = tuple(min(4, cells) for cells in self.archive_dims)
        if space.fault is not None:
            # Mutants only where the search makes them; their Gaussian step only where they are continuous.
            applies = {"experimental.min_predicted": True, "selection.elite_mutants": run.mutates_elites,
                       "experimental.mutant_sigma": run.mutates_elites and run.qd.emitter != "map_elites",
                       "search": run.can_search_auto}
            run.assign({key: value for key, value in FAULT_SEARCH.items() if key not in given and applies[key]})

    def validate(self, need: Callable[[bool, str, str], None]) -> None:
        need(self.episodes >= 1, "episodes", "must be positive")
        need(bool(self.space or self.params), "space", "give a space (a shipped name or a TOML file) or params")
        need(not self.archive_dims or all(d >= 1 for d in self.archive_dims), "archive_dims", "must be positive")


#: Keys every gym preset shares. A parameter measure is exact (the level holds it), so the surrogate's prediction
#: of it is replaced by the level's own value, and each 4 × 4 block's pick is the elite expected to add most to the
#: archive. CMA-ME searches the continuous box in the inner loop. No elite mutants beside the picks (Maze audits
#: take 150): on the LunarLander tuning seeds (1, 2) dropping the 15 that gym audits took raised the failing cells
#: from 48 and 39 to 67 and 56; a pick of the 40 highest gains wherever they are found no more (74 and 50, and 33
#: against 65 on seed 3; docs/results/gym_audit).
_SEARCH = {
    "surrogate.exact_level_values": True,
    "qd.emitter": "cma_me",
    "qd.num_emitters": 5,
    "qd.batch_size": 30,
    "qd.sigma0": 0.2,
    "selection.block": (4, 4),
}

#: A space that declares a ``[fault]`` (a yes or no per episode): DSAGE picks only the levels its surrogate predicts
#: to be faults, each block's largest predicted gain, and beside them plays 20 mutants of the faults found, one
#: small step away (1% of the box's half-width), each outer iteration. On the peers' tasks the floor took
#: LunarLander's fault cells from 14 to 24 in 200 episodes (tuning seed 1), and the mutants CartPole's from 14.5 to
#: 23 and its faults from 62 to 152 at equal CPU time (tuning seeds 1-2; fresh seeds: docs/DECISIONS.md). The run
#: is ``search = "auto"`` where it can be: where an episode costs next to nothing (Taxi, 2 ms) the direct search
#: finds more fault cells in the same time, and where it does not (LunarLander, CartPole) ``auto`` stays DSAGE.
#: Keys the caller sets stay as set.
FAULT_SEARCH: dict[str, Any] = {
    "experimental.min_predicted": 0.5,
    "selection.elite_mutants": 20,
    "experimental.mutant_sigma": 0.01,
    "search": "auto",
}

#: ``demo`` is the few-minute audit a newcomer pastes; ``cpu`` an audit of a named agent on 2 cores; ``tiny``
#: for tests and smoke runs.
PRESETS: dict[str, dict[str, Any]] = {
    "paper": {**_SEARCH, "budget": 5_000, "n_rand": 200, "qd.exploit_iterations": 1_000, "surrogate.epochs": 20},
    "cpu": {**_SEARCH, "budget": 1_000, "n_rand": 100, "gym.episodes": 10, "qd.exploit_iterations": 200,
            "surrogate.epochs": 20, "surrogate.batch_size": 16},
    "demo": {**_SEARCH, "budget": 300, "n_rand": 60, "gym.episodes": 10, "qd.exploit_iterations": 100,
             "surrogate.epochs": 20, "surrogate.batch_size": 16},
    "tiny": {**_SEARCH, "budget": 40, "n_rand": 20, "gym.episodes": 2, "qd.exploit_iterations": 5,
             "qd.num_emitters": 2, "qd.batch_size": 10, "surrogate.epochs": 2, "surrogate.batch_size": 8,
             "selection.block": (2, 2)},
}

_DIRECT = {"surrogate.kind": "none", "qd.num_emitters": 5, "qd.batch_size": 30}
#: The baselines on the same box, none with a surrogate: MAP-Elites (Gaussian mutation), CMA-ME, and the falsifiers
#: people use for this job (VerifAI's samplers): random (``dr``, common to every domain), Halton, cross-entropy.
VARIANTS: dict[str, dict[str, Any]] = {
    "map_elites": {**_DIRECT, "qd.emitter": "gaussian"},
    "cma_me": {**_DIRECT, "qd.emitter": "cma_me"},
    "halton": {**_DIRECT, "qd.emitter": "halton"},
    # One distribution refitted to the worst fifth of each batch of 30.
    "cross_entropy": {**_DIRECT, "qd.emitter": "cross_entropy", "qd.num_emitters": 1},
}

#: ``dsage-ray audit``'s flags of an audit of any Gymnasium environment, each a key of this section
#: (``--param`` and ``--env-arg`` repeat).
AUDIT_FLAGS = (
    AuditFlag(flag="--env", key="env", metavar="ID",
              help="the environment id, e.g. CartPole-v1 (default: the space's)"),
    AuditFlag(flag="--space", key="space", metavar="FILE|NAME",
              help="the parameter space: a TOML file, a shipped one (cartpole, the default; `dsage-ray gym spaces` "
                   "lists them all), or '' for --env and --param alone"),
    AuditFlag(flag="--param", key="params", metavar="NAME=LOW:HIGH", repeat=True,
              help="a searched parameter (repeat): NAME=LOW:HIGH (a gym.make keyword), attr.NAME=LOW:HIGH (an "
                   "attribute of env.unwrapped after reset), reset.NAME=LOW:HIGH (a reset option); LOW:HIGH:int for "
                   "integers, A|B|C for choices"),
    AuditFlag(flag="--env-arg", key="env_args", metavar="KEY=VALUE", repeat=True,
              help="a fixed gym.make keyword (repeat), e.g. enable_wind=true"),
    AuditFlag(flag="--space-set", key="space_set", metavar="LINE", repeat=True,
              help="a line of a space file (repeat), e.g. 'success.return_at_least = 200' or "
                   "'measures.x_end = {obs = 0, at = \"end\", range = [-1.5, 1.5]}' (docs/GYM.md)"),
)


DOMAIN = DomainSpec(
    name="gym",
    config=GymConfig,
    domain="dsage_ray.domains.gym.domain:GymDomain",
    presets=PRESETS,
    variants=VARIANTS,
    # search = "auto" continues with the cross-entropy falsifier: the best search without a surrogate at equal CPU
    # time on the behaviour maps and on CartPole's parameter map; on LunarLander's, Halton and random fill more
    # cells (docs/results/gym_audit). On the peers' Taxi task, continuing with MAP-Elites found fewer fault
    # cells and faults (docs/results/peers/record.md).
    direct_search="cross_entropy",
    comparison=("dsage", "map_elites", "cma_me", "dr", "halton", "cross_entropy"),
    audit=AuditSpec(
        objectives=("failure_rate",),
        measures=(),  # the space's [audit] measures
        default_agent="rllib:ppo_cartpole",
        episodes_key="gym.episodes",
        # Every numeric entry key is a column: the mean and worst return, the mean length, each parameter.
        settings=(ReportField(key="env", label="environment"),
                  ReportField(key="success", label="an episode succeeds when"),
                  ReportField(key="max_steps", label="step limit", format="{} steps per episode")),
        flags=AUDIT_FLAGS,
        flags_title="any Gymnasium environment (--domain gym)",
        summary="any Gymnasium environment: --env, --space, --param",
        nominal="the environment as registered, or the space's [nominal] values",
        measures_note="the space's [audit] measures",
        examples=(
            "dsage-ray audit --domain gym --env CartPole-v1 --space cartpole --agent rllib:ppo_cartpole --preset demo",
            "dsage-ray audit --domain gym --env LunarLander-v3 --param gravity=-11.9:-2 --env-arg enable_wind=true \\",
            "    --space '' --space-set 'success.return_at_least = 200' --agent sb3:model.zip    # no space file",
        ),
    ),
    # dsage_ray's generic kinds (dsage_ray/agents/kinds.py) over the environment's spaces.
    agents=AgentKinds(forms={
        "rllib": "rllib:PATH", "sb3": "sb3:PATH.zip", "torchscript": "torchscript:PATH",
        "qtable": "qtable:PATH.npy", "python": "python:MODULE:FUNCTION", "random": "random",
    }),
    cli="dsage_ray.domains.gym.cli",
)
