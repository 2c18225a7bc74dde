"""One typed, serialisable config object per run.

A :class:`RunConfig` is a tree of dataclasses. Its flat form uses dotted keys
(``"surrogate.epochs"``), which map 1:1 onto ``tune.grid_search`` axes and ``--set`` overrides.

The run's domain has a section named after it (``maze.episodes``), a dataclass the domain's
registration supplies (:mod:`dsage_ray.domains.registry`), as are the domain's presets and
variants; this module knows no domain by name.

Resolution order when building a config: dataclass defaults → the domain's *preset* → the
*variant* → explicit keys. ``preset`` and ``variant`` are ordinary fields, so a Tune grid over
``variant`` is an ablation grid.
"""

from __future__ import annotations

import dataclasses
import difflib
import functools
import json
import tomllib
import types
import typing
from pathlib import Path
from typing import Any, Collection, Literal, Mapping

import numpy as np

from dsage_ray.domains.registry import domain_names, get_domain
from dsage_ray.errors import InputError, did_you_mean


class ConfigError(InputError):
    """An invalid config; the message names the offending key."""


# The closed sets of names a config value picks from. Each is the key set of the table that
# implements the names (checked equal in tests/test_config.py); the tables live with their code,
# which imports pyribs or the simulators, so config validation can stay import-free.

#: Keys of :data:`dsage_ray.qd.optimizer.EMITTERS`.
EmitterName = Literal["map_elites", "cma_me", "random", "gaussian", "halton", "cross_entropy"]
#: The emitters with a mutation, the keys of :data:`dsage_ray.qd.mutants.MUTATIONS` (``selection.elite_mutants``).
MutatingEmitter = Literal["map_elites", "cma_me", "gaussian", "halton", "cross_entropy"]
#: Keys of :data:`dsage_ray.qd.selection.SELECTION_METHODS`.
SelectionMethod = Literal["downsample", "random", "full"]
#: Surrogate kinds: ancillary occupancy (``two_stage``), without it (``one_stage``), none (plain QD).
SurrogateKind = Literal["two_stage", "one_stage", "none"]
#: Surrogate prediction arithmetic.
Precision = Literal["auto", "fp32", "bf16"]
#: ``fixed``: the variant runs as set; ``auto``: DSAGE, then the domain's direct search if the surrogate costs more
#: than it buys (:mod:`dsage_ray.core.auto_search`).
SearchMode = Literal["fixed", "auto"]


def key(default: Any, *, status: str, values: str = "", note: str = "") -> Any:
    """A config field with what ``dsage-ray config`` and docs/CONFIG.md say about it.

    Args:
        default: The default value (a tuple stays immutable; no factory needed).
        status: ``paper`` (the paper's algorithm or value), ``tool`` (how the tool runs, not the search),
            ``default-on`` (beyond the paper, on in the presets or audits that ``note`` names), ``opt-in`` (beyond the
            paper, measured to help where ``note`` says, not yet on in a preset) or ``experimental`` (beyond the paper
            and off; ``note`` gives its measured effect).
        values: The values it takes, where its type does not say (``>= 1``, ``(0, 1]``).
        note: One line: what it does, and where measured, what it did.
    """
    return dataclasses.field(default=default, metadata={"status": status, "values": values, "note": note})


@dataclasses.dataclass
class SurrogateConfig:
    """The deep surrogate model (SPEC: the surrogate)."""

    kind: SurrogateKind = key("two_stage", status="paper",
                              note="two_stage predicts the agent's occupancy first (ancillary data); none: plain QD")
    epochs: int = key(200, status="paper", values=">= 1", note="epochs of each training on the recent window")
    batch_size: int = key(64, status="paper", values=">= 1", note="Adam's minibatch size in each training")
    lr: float = key(1e-3, status="paper", values="> 0", note="Adam's learning rate")
    occupancy_weight: float = key(10.0, status="paper", values=">= 0",
                                  note="weight of the occupancy loss in the two-stage model's loss")
    train_window: int = key(20_000, status="paper", values=">= 1", note="the most recent evaluations trained on")
    #: Width of the networks (the first convolution of both predictors); 64 is the paper's. The residual
    #: blocks' cost grows as its square (benchmarks/bench_surrogate.py prints FLOPs and predictions/s).
    channels: int = key(64, status="paper", values=">= 1",
                        note="network width; 16 cut the surrogate's share of a Maze cpu run from ≈50% to 17% for "
                             "5% less QD-score (docs/DECISIONS.md)")
    #: Prediction arithmetic: ``fp32``, ``bf16`` (the two-stage model's residual blocks, most of its work,
    #: under bf16 autocast) or ``auto`` (bf16 on CUDA and on CPUs with native bf16, else fp32). Training is
    #: always fp32. ``auto`` resolves per machine, as ``device`` does.
    precision: Precision = key("auto", status="default-on",
                               note="prediction arithmetic; auto: bf16 where the CPU or GPU has it, else fp32")
    device: str = key("auto", status="tool", values="auto, cpu, cuda, cuda:N",
                      note="where the surrogate trains and predicts; auto: CUDA when available")
    #: Warm start (beyond the paper): a file of ``dsage-ray surrogate pretrain``, or an earlier surrogate
    #: run, audit or trial folder (or its ``checkpoint.dsage``). Its weights start this run's surrogate and
    #: the first outer iteration exploits them instead of evaluating ``n_rand`` random levels
    #: (:mod:`dsage_ray.core.warm_start`). Empty: a cold start (the paper). Made absolute when the
    #: config is built (Tune trials run in their own folder).
    init: str = key("", status="default-on", values="PATH or empty",
                    note="warm start from a pretrained surrogate or an earlier run (audit-series uses it)")
    #: Take the measures (and objective) that are functions of the level alone from the level itself, not from
    #: the network (Maze: ``num_walls``, ``optimal_path_length`` and the ``validity`` objective; Mario: ``sky_tiles``),
    #: through the domain's ``level_values``. The network still trains on them. Off (the paper): everything is
    #: predicted, so a pick can land a few wall counts away from the cell the inner loop chose it for.
    exact_level_values: bool = key(False, status="default-on",
                                   note="take measures a level fixes by itself from the level "
                                        "(audits; docs/DECISIONS.md)")
    #: Name of a measure that equals the sum of the occupancy grid (Maze: ``mean_path_length``, since
    #: the grid counts the agent's steps); a two-stage surrogate then predicts it as the sum of its
    #: predicted occupancy instead of with its own head. Empty (the paper): every measure has a head.
    occupancy_sum_measure: str = key("", status="default-on", values="a measure name or empty",
                                     note="predict this measure as the predicted occupancy's sum (Maze cpu preset: "
                                          "QD-score 1,597 ± 17.5 against 1,423.7 ± 24.7)")
    #: Name of a measure the domain has a parameter-free prior for (Maze: ``mean_path_length``, the expected
    #: steps of a uniform random walker from the start to the goal). Its prediction is then the mean of the
    #: network's and the prior's, the prior mapped to the measure by a least-squares line on
    #: ``log(1 + prior)`` fitted to the training window after each training. Empty (the paper): the network alone.
    prior_measure: str = key("", status="default-on", values="a measure name or empty",
                             note="blend this measure's prediction with the domain's prior (Maze cpu preset: "
                                  "30% lower error on the picks, QD-score level)")


@dataclasses.dataclass
class QDConfig:
    """The QD optimizer used on the surrogate (inner loop) or directly (baselines)."""

    #: ``map_elites`` (discrete bitmaps), ``cma_me`` (continuous latents), ``random`` (DR), or for continuous
    #: vectors in a box (the domain's ``solution_bounds``, else [-1, 1]): ``gaussian`` (MAP-Elites with Gaussian
    #: mutation of ``sigma0``), ``halton`` (quasi-random samples) or ``cross_entropy`` (a cross-entropy falsifier).
    emitter: EmitterName = key("map_elites", status="paper", note="the QD search, in the inner loop or alone")
    num_emitters: int = key(5, status="paper", values=">= 1", note="emitters asking in parallel each step")
    batch_size: int = key(30, status="paper", values=">= 1", note="solutions each emitter asks for per step")
    #: MAP-Elites: cells mutated per offspring.
    mutation_cells: int = key(10, status="paper", values=">= 1", note="MAP-Elites: tiles changed per mutation")
    #: CMA-ME's initial step size; ``gaussian``'s mutation std.
    sigma0: float = key(0.2, status="paper", values="> 0", note="CMA-ME's initial step; the Gaussian mutation's std")
    #: Inner-loop iterations (N_exploit) per outer iteration.
    exploit_iterations: int = key(10_000, status="paper", values=">= 1", note="inner-loop steps per outer iteration")


@dataclasses.dataclass
class SelectionConfig:
    """Which surrogate elites get a real evaluation."""

    method: SelectionMethod = key("downsample", status="paper", note="how picks are taken from the surrogate archive")
    #: Downsampling block in archive cells per measure.
    block: tuple[int, ...] = key((8, 6), status="paper", values="one size per measure",
                                 note="downsampling block, in archive cells per measure")
    #: ``random``: how many elites to pick.
    count: int = key(432, status="paper", values=">= 1", note="random selection: how many elites")
    #: Each outer iteration after the first, also evaluate this many mutants of the ground-truth archive's best
    #: elites (``experimental.elite_share``), beside the surrogate's picks (not in the paper;
    #: :mod:`dsage_ray.qd.mutants`). The mutation is MAP-Elites' (``qd.mutation_cells``) for bitmaps, Gaussian
    #: (``qd.sigma0``, clipped to the domain's ``solution_bounds``) for the continuous emitters' vectors. An audit's
    #: never-solved levels are the best elites, and a mutant of one is often never solved too, which the surrogate
    #: cannot predict within a cell. 0 (the paper): only the surrogate's picks.
    elite_mutants: int = key(0, status="default-on", values=">= 0",
                             note="mutants of the best elites beside the picks (audits; docs/DECISIONS.md)")
    #: Before the real evaluation, screen the picks and more candidates with this many episodes each (the domain's
    #: ``screen``: Maze only) and evaluate, up to the selection's size, those whose screened result adds to the
    #: ground truth (not in the paper; :mod:`dsage_ray.qd.screen`). MAP-Elites (``qd.emitter = "map_elites"``
    #: without a surrogate) screens mutants of its elites instead, once its random start-up is over. 0 (the
    #: paper): evaluate the picks as chosen.
    screen_episodes: int = key(0, status="opt-in", values=">= 0",
                               note="play candidates this many episodes before evaluating (Maze; docs/DECISIONS.md)")
    #: With ``screen_episodes``: keep the screened candidates expected to add most to the ground truth per expected
    #: cost, judged by the screen's errors on recently evaluated levels and the domain's cost model
    #: (``evaluation_cost`` of its config section: Maze's grows with the mean path length), instead of those whose
    #: screened cell alone would add, in the order screened (not in the paper; :func:`dsage_ray.qd.screen.keep_screened`).
    screen_gain: bool = key(False, status="opt-in",
                            note="rank screened candidates by expected gain per cost (on in the Maze cpu preset: "
                                 "1.15× MAP-Elites at equal CPU time, docs/DECISIONS.md)")


@dataclasses.dataclass
class RayConfig:
    """How a run uses Ray (ignored by the in-process runner): simulator actors and the trial's resources."""

    num_workers: int = key(2, status="tool", values=">= 0",
                           note="simulator actors in the pool (0: evaluate in the trial process)")
    cpus_per_worker: float = key(0.5, status="tool", values="> 0", note="logical CPUs each simulator actor reserves")
    trial_cpus: float = key(1.0, status="tool", values="> 0",
                            note="logical CPUs the trial reserves (surrogate training and the inner loop)")


@dataclasses.dataclass
class ExperimentalConfig:
    """Beyond the paper and off by default: each was measured, and none is a clear win where it was tried.

    ``dsage-ray config --experimental`` lists them with what they did; docs/CONFIG.md links the measurements.
    """

    #: Random valid levels evaluated once, outside the budget, to score the surrogate on levels it
    #: never trains on (``holdout_*`` metrics each outer iteration); 0 turns it off.
    holdout_levels: int = key(0, status="experimental", values=">= 0",
                              note="levels held out to score the surrogate each iteration; a diagnostic, "
                                   "+5% evaluations at 100 (surrogate_accuracy)")
    #: With ``surrogate.init``: its dataset becomes the oldest part of this run's dataset, so it weighs in the first
    #: trainings and leaves the ``train_window`` as this run's evaluations arrive. Off: weights only.
    init_prior: bool = key(True, status="experimental",
                           note="with surrogate.init, also train on the source's levels; every measured warm start had it on")
    #: ``selection.elite_mutants``: the parents are drawn uniformly among this share of the ground-truth elites,
    #: the best by objective (ties with the last one included).
    elite_share: float = key(0.05, status="experimental", values="(0, 1]",
                             note="share of best elites the mutants' parents come from (tuned on one seed)")
    #: ``selection.screen_episodes``: candidates screened per pick (the picks, then other elites predicted to add),
    #: or per level of a MAP-Elites batch.
    screen_pool: float = key(4.0, status="experimental", values=">= 1",
                             note="candidates screened per pick; 3 and 6 level with 4 (docs/DECISIONS.md)")
    #: ``selection.screen_episodes``: the agent's arithmetic in the screen. ``fp32``: the agent as it is
    #: evaluated; ``bf16``: its matrix products in bf16, where the agent has such a copy
    #: (``Agent.reduced_precision``: the ``dcd`` agents); ``auto``: bf16 on a CPU with native bf16 arithmetic,
    #: else fp32. Evaluations always run the agent as it is.
    screen_precision: Precision = key("auto", status="experimental",
                                      note="the screen's agent arithmetic; bf16 cut the screen's share 6.7% → 4.8% "
                                           "(docs/DECISIONS.md)")
    #: ``selection.screen_gain``: how many of the latest evaluated levels' screen errors are kept.
    gain_window: int = key(1000, status="experimental", values=">= 1",
                           note="screen_gain: recent levels whose screen errors are kept (not tuned)")
    #: ``selection.screen_gain``: how many of them, nearest in screened measures, lend a candidate their errors.
    gain_neighbours: int = key(64, status="experimental", values=">= 1",
                               note="screen_gain: nearest levels lending a candidate their errors (not tuned)")
    #: Solutions per pool task; 0 picks ~8 chunks per actor per batch, 1 spreads uneven episodes best, larger
    #: amortises Ray's per-task round trip.
    chunk_size: int = key(0, status="experimental", values=">= 0 (0: automatic)",
                          note="solutions per Ray pool task (performance)")


@dataclasses.dataclass
class RunConfig:
    """Everything one DSAGE run needs; serialisable to JSON/TOML and back."""

    name: str = key("dsage", status="tool", values="a relative folder name",
                    note="the run's folder under tb_logs/ (or --out)")
    domain: str = key("maze", status="tool", values="a registered domain", note="maze, mario, gym, or a plug-in's")
    variant: str = key("dsage", status="paper", values="a variant of the domain",
                       note="the search: dsage, its ablations, or a baseline (sets other keys)")
    #: ``auto``: continue with the domain's direct search (``DomainSpec.direct_search``) on the same archive, with a
    #: time budget right after the random iteration when too few surrogate iterations fit in the time left, else
    #: after DSAGE's first surrogate iteration when a level DSAGE picked cost more than
    #: :data:`~dsage_ray.core.auto_search.BREAK_EVEN_COST_RATIO` times a random one, surrogate time included.
    search: SearchMode = key("fixed", status="opt-in",
                             note="auto: DSAGE, or the domain's direct search where the surrogate costs more than it "
                                  "buys (docs/DECISIONS.md); audits with a time budget take it unless told")
    preset: str = key("paper", status="tool", values="a preset of the domain",
                      note="the scale: paper, cpu, demo or tiny (sets other keys)")
    seed: int = key(0, status="tool", note="the run's seed; the same seed and config give the same archive")
    #: Total real evaluations.
    budget: int = key(100_000, status="paper", values=">= 1", note="real evaluations")
    #: Seconds of wall time the run may spend stepping, cumulative across resumes; 0: no limit. Whichever
    #: of ``budget`` and ``time_budget`` is reached first ends the run at a clean checkpoint; a time budget
    #: that runs out during an evaluation stops the batch there (the levels under way finish). Where a time
    #: budget ends a run depends on the machine and its load, so such a run is not reproducible; an
    #: evaluation-budget run is. Raising it and resuming continues the run (the only key a resume may change).
    time_budget: float = key(0.0, status="tool", values=">= 0 seconds (0: none)",
                             note="also stop after this much stepping time (--time-budget 10m)")
    #: Random solutions evaluated in outer iteration 1.
    n_rand: int = key(100, status="paper", values=">= 1", note="random levels evaluated first")
    #: Outer iterations between TensorBoard images (heatmaps and elite levels); 0: none.
    image_every: int = key(5, status="tool", values=">= 0 (0: none)",
                           note="outer iterations between TensorBoard images")
    #: Torch threads of the process running the outer loop (surrogate training and predictions),
    #: pinned during every outer iteration in every mode (``--local``, a Tune trial, a resumed run).
    #: A float sum split over more threads rounds differently, so the count is part of the run's
    #: config, never taken from the machine. A lone Tune trial may use every CPU of its placement
    #: group: its surrogate phases never overlap its simulators' evaluations.
    torch_threads: int = key(1, status="tool", values=">= 1",
                             note="torch threads of the surrogate (part of the config: it changes the rounding)")
    #: Pipelined outer loop (DSAGE only): while iteration k's picks are evaluated, the surrogate trains on
    #: the evaluations up to iteration k-1 and picks iteration k+1's levels. With simulators in other
    #: processes (the Ray pool) the two overlap, so the surrogate's time hides behind the simulators'; in
    #: one process they run one after the other. Either way a run computes the same thing, so a seed
    #: gives the same archive in-process and through Tune. The price: each selection is made by a
    #: surrogate one batch behind.
    pipeline: bool = key(False, status="opt-in",
                         note="train and pick while the last picks are evaluated by Ray actors (docs/DECISIONS.md)")
    surrogate: SurrogateConfig = dataclasses.field(default_factory=SurrogateConfig)
    qd: QDConfig = dataclasses.field(default_factory=QDConfig)
    selection: SelectionConfig = dataclasses.field(default_factory=SelectionConfig)
    ray: RayConfig = dataclasses.field(default_factory=RayConfig)
    experimental: ExperimentalConfig = dataclasses.field(default_factory=ExperimentalConfig)
    #: Domain sections by domain name (``config.maze`` reads ``sections["maze"]``): the run's own
    #: domain always, any other registered domain only when a key of its section was given. Each is
    #: the dataclass its registration names (:class:`dsage_ray.domains.registry.DomainSpec`).
    sections: dict[str, Any] = dataclasses.field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.domain not in self.sections and self.domain in domain_names():
            self.section(self.domain)

    def __getattr__(self, name: str) -> Any:
        # Only reached when ordinary lookup fails; ``__dict__`` directly, so unpickling (no
        # attributes yet) does not recurse.
        sections = self.__dict__.get("sections")
        if sections is not None and name in sections:
            return sections[name]
        raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}"
                             + (f" (no {name!r} section in this {self.__dict__.get('domain')!r} config)"
                                if sections is not None and name in domain_names() else ""))

    def section(self, domain: str) -> Any:
        """The config section of a registered ``domain``, added with its defaults if the config has none."""
        if domain not in self.sections:
            if domain in _field_types(RunConfig):
                raise ConfigError(f"domain {domain!r}: the name of a domain cannot be a key of the run config")
            self.sections[domain] = get_domain(domain).config()
        return self.sections[domain]

    # ----------------------------------------------------------------------------------- building

    @classmethod
    def build(cls, values: Mapping[str, Any] | None = None, **kwargs: Any) -> "RunConfig":
        """Builds a validated config from flat (dotted) or nested values plus keyword overrides."""
        explicit = upgrade_keys(flatten(dict(values or {})))
        explicit.update(upgrade_keys(flatten(kwargs)))
        # Built with its domain, so only that domain's section (and registration) is ever loaded.
        base = cls(**{key: _coerce(key, explicit[key], _field_types(cls)[key])
                      for key in ("domain", "preset", "variant") if key in explicit})
        layered: dict[str, Any] = {}
        try:
            preset_table = presets(base.domain)
        except InputError as exc:
            raise ConfigError(f"domain: {exc}") from None
        if base.preset not in preset_table:
            raise ConfigError(f"preset: unknown preset {base.preset!r} for domain {base.domain!r} "
                              f"(known: {sorted(preset_table)}){did_you_mean(base.preset, preset_table)}")
        layered.update(preset_table[base.preset])
        variant_table = variants(base.domain)
        if base.variant not in variant_table:
            raise ConfigError(f"variant: unknown variant {base.variant!r} for domain {base.domain!r} "
                              f"(known: {sorted(variant_table)}){did_you_mean(base.variant, variant_table)}")
        layered.update(variant_table[base.variant])
        layered.update(explicit)
        config = cls(domain=base.domain)
        _assign(config, layered)
        # A section whose keys depend on each other fills in what was left to it (the gym domain's measures
        # come from its space file), before validation sees them.
        complete = getattr(config.domain_config, "complete", None)
        if complete is not None:
            complete(config)
        if config.surrogate.init:
            config.surrogate.init = str(Path(config.surrogate.init).expanduser().resolve())
        config.validate()
        return config

    @classmethod
    def from_file(cls, path: str | Path, overrides: Mapping[str, Any] | None = None) -> "RunConfig":
        """Reads a TOML or JSON config file, then applies dotted ``overrides``."""
        values = read_config_file(path)
        values.update(flatten(dict(overrides or {})))
        return cls.build(values)

    def to_dict(self) -> dict[str, Any]:
        """Nested plain-Python form (lists for tuples), JSON/TOML friendly; domain sections sit at the
        top level beside the others (``{"maze": {...}, "surrogate": {...}}``)."""
        data: dict[str, Any] = {}
        for field in dataclasses.fields(self):
            value = getattr(self, field.name)
            if field.name == "sections":
                continue
            if dataclasses.is_dataclass(value) and not data.keys() & self.sections.keys():
                # Domain sections first among the sections, as they were when Maze and Mario were fields.
                data.update({name: dataclasses.asdict(section) for name, section in self.sections.items()})
            data[field.name] = dataclasses.asdict(value) if dataclasses.is_dataclass(value) else value
        return json.loads(json.dumps(data))

    def to_flat(self) -> dict[str, Any]:
        """Dotted-key form, e.g. for ``tune.Tuner(param_space=...)``."""
        return flatten(self.to_dict())

    def replace(self, **dotted: Any) -> "RunConfig":
        values = self.to_flat()
        values.update({k.replace("__", "."): v for k, v in dotted.items()})
        return RunConfig.build(values)

    # --------------------------------------------------------------------------------- validation

    @property
    def domain_config(self) -> Any:
        """The run's domain section (``config.maze`` for a Maze run)."""
        return self.section(self.domain)

    @property
    def uses_surrogate(self) -> bool:
        return self.surrogate.kind != "none"

    @property
    def mutates_elites(self) -> bool:
        """A surrogate search whose QD emitter has a mutation: ``selection.elite_mutants`` can apply."""
        return self.uses_surrogate and self.qd.emitter in typing.get_args(MutatingEmitter)

    def validate(self) -> None:
        """Raises :class:`ConfigError` naming the first key with an impossible value."""
        def need(cond: bool, key: str, why: str) -> None:
            if not cond:
                raise ConfigError(f"{key}: {why} (got {_get(self, key)!r})")

        _check_choices(self)
        try:
            get_domain(self.domain)
        except InputError as exc:
            raise ConfigError(f"domain: {exc}") from None
        for name, section in self.sections.items():
            _check_choices(section, f"{name}.")
        # The name is a folder under tb_logs/ (or --out): it may not climb out of it.
        need(bool(self.name) and not Path(self.name).is_absolute() and ".." not in Path(self.name).parts, "name",
             "must be a relative folder name without '..' (runs are written under tb_logs/ or --out)")
        need(self.budget >= 1, "budget", "must be positive")
        need(self.time_budget >= 0, "time_budget", "must be >= 0 seconds (0: no limit)")
        need(self.n_rand >= 1, "n_rand", "must be positive")
        need(self.budget >= self.n_rand or not self.uses_surrogate, "budget",
             f"must be at least n_rand={self.n_rand} (the first outer iteration evaluates n_rand solutions)")
        need(self.image_every >= 0, "image_every", "must be >= 0 (0: no images)")
        need(self.torch_threads >= 1, "torch_threads", "must be positive")
        for key in ("epochs", "batch_size", "train_window", "channels"):
            need(getattr(self.surrogate, key) >= 1, f"surrogate.{key}", "must be positive")
        need(self.surrogate.lr > 0, "surrogate.lr", "must be positive")
        need(self.surrogate.occupancy_weight >= 0, "surrogate.occupancy_weight", "must be >= 0")
        need(self.experimental.holdout_levels >= 0, "experimental.holdout_levels", "must be >= 0 (0: off)")
        need(not self.surrogate.init or self.uses_surrogate, "surrogate.init",
             "a warm start needs a surrogate (this variant runs without one)")
        need(not self.surrogate.occupancy_sum_measure or self.surrogate.kind != "one_stage",
             "surrogate.occupancy_sum_measure", "needs the two-stage surrogate (only it predicts occupancy)")
        measure_names = getattr(self.sections[self.domain], "measures", None)
        need(not self.surrogate.occupancy_sum_measure or measure_names is None
             or self.surrogate.occupancy_sum_measure in measure_names, "surrogate.occupancy_sum_measure",
             f"{self.surrogate.occupancy_sum_measure!r} is not one of the measures {list(measure_names or [])}")
        need(not self.surrogate.prior_measure or measure_names is None
             or self.surrogate.prior_measure in measure_names, "surrogate.prior_measure",
             f"{self.surrogate.prior_measure!r} is not one of the measures {list(measure_names or [])}")
        for key in ("num_emitters", "batch_size", "exploit_iterations", "mutation_cells"):
            need(getattr(self.qd, key) >= 1, f"qd.{key}", "must be positive")
        need(self.qd.sigma0 > 0, "qd.sigma0", "must be positive")
        need(self.selection.count >= 1, "selection.count", "must be positive")
        need(self.uses_surrogate or not self.pipeline, "pipeline",
             "pipelines the surrogate's phases with the evaluations; this variant has no surrogate")
        if self.search == "auto":
            need(self.uses_surrogate, "search", f"auto starts as DSAGE; variant {self.variant!r} has no surrogate")
            need(bool(get_domain(self.domain).direct_search), "search",
                 f"auto needs the domain's direct search; domain {self.domain!r} declares none")
            need(not self.pipeline, "search", "auto reads the surrogate's cost from an iteration that did not overlap "
                                              "the evaluations; set pipeline = false")
            need(not self.surrogate.init, "search", "auto compares the surrogate's levels with the random first "
                                                    "ones, which a warm start (surrogate.init) skips")
        need(self.selection.elite_mutants >= 0, "selection.elite_mutants", "must be >= 0 (0: none)")
        need(self.uses_surrogate or not self.selection.elite_mutants, "selection.elite_mutants",
             "adds mutants to a surrogate's picks; this variant's QD search mutates its elites already")
        need(self.mutates_elites or not self.selection.elite_mutants, "selection.elite_mutants",
             f"mutates with qd.emitter's operator; {self.qd.emitter!r} has none (use "
             f"{' or '.join(typing.get_args(MutatingEmitter))})")
        need(0.0 < self.experimental.elite_share <= 1.0, "experimental.elite_share", "must be in (0, 1]")
        need(self.selection.screen_episodes >= 0, "selection.screen_episodes", "must be >= 0 (0: no screen)")
        need(self.uses_surrogate or self.qd.emitter == "map_elites" or not self.selection.screen_episodes,
             "selection.screen_episodes", f"screens a surrogate's picks, or MAP-Elites' mutants; qd.emitter "
             f"{self.qd.emitter!r} without a surrogate adapts to every level it asked for")
        need(self.experimental.screen_pool >= 1, "experimental.screen_pool",
             "must be >= 1 (candidates screened per pick)")
        need(self.selection.screen_episodes > 0 or not self.selection.screen_gain, "selection.screen_gain",
             "ranks screened candidates; set selection.screen_episodes > 0 to screen, or screen_gain = false")
        need(self.experimental.gain_window >= 1, "experimental.gain_window", "must be positive")
        need(self.experimental.gain_neighbours >= 1, "experimental.gain_neighbours", "must be positive")
        need(self.ray.num_workers >= 0, "ray.num_workers", "must be >= 0")
        need(self.ray.cpus_per_worker > 0, "ray.cpus_per_worker", "must be positive")
        need(self.ray.trial_cpus > 0, "ray.trial_cpus", "must be positive")
        need(self.experimental.chunk_size >= 0, "experimental.chunk_size", "must be >= 0 (0: automatic)")
        dom = self.domain_config
        prefix = self.domain
        need(len(dom.measures) >= 1, f"{prefix}.measures", "needs at least one measure")
        need(len(dom.archive_dims) == len(dom.measures), f"{prefix}.archive_dims",
             f"needs one entry per measure ({len(dom.measures)})")
        need(all(d >= 1 for d in dom.archive_dims), f"{prefix}.archive_dims", "cells per measure must be positive")
        if dom.measure_ranges:
            need(len(dom.measure_ranges) == len(dom.measures), f"{prefix}.measure_ranges",
                 f"needs one (low, high) pair per measure ({len(dom.measures)})")
            need(all(len(r) == 2 and r[0] < r[1] for r in dom.measure_ranges), f"{prefix}.measure_ranges",
                 "each range must be (low, high) with low < high")
        need(len(self.selection.block) == len(dom.measures), "selection.block",
             f"needs one block size per measure ({len(dom.measures)})")
        need(all(b >= 1 for b in self.selection.block), "selection.block", "block sizes must be positive")
        check = getattr(dom, "validate", None)
        if check is not None:
            check(lambda cond, key, why: need(cond, f"{prefix}.{key}", why))


# ------------------------------------------------------------------------------- renamed, removed

#: Keys moved into the ``experimental`` section (old name → new name). A config file, ``--set`` or a stored
#: run naming the old key still works.
RENAMED_KEYS: dict[str, str] = {
    "surrogate.holdout_levels": "experimental.holdout_levels",
    "surrogate.init_prior": "experimental.init_prior",
    "selection.elite_share": "experimental.elite_share",
    "selection.screen_pool": "experimental.screen_pool",
    "selection.screen_precision": "experimental.screen_precision",
    "selection.gain_window": "experimental.gain_window",
    "selection.gain_neighbours": "experimental.gain_neighbours",
    "ray.chunk_size": "experimental.chunk_size",
}


@dataclasses.dataclass(frozen=True)
class RemovedKey:
    """A key that is gone: the values it could hold that behave as today, and why it went."""

    accepted: tuple[Any, ...]
    why: str


_NOT_HELPING = "measured not to help"
#: Removed keys. A stored run (or a file) holding an accepted value loads as before; any other value is refused
#: with the reason, since today's code would run something else.
REMOVED_KEYS: dict[str, RemovedKey] = {
    "selection.expected_gain": RemovedKey((False,), f"{_NOT_HELPING} (docs/DECISIONS.md)"),
    "selection.min_gain": RemovedKey((0.0,), f"{_NOT_HELPING}: expected_gain's threshold"),
    "selection.prefer_new_cells": RemovedKey((False,), f"{_NOT_HELPING} (docs/DECISIONS.md)"),
    "selection.skip_filled": RemovedKey((False,), f"{_NOT_HELPING}: the dsage_novel variant was level with dsage "
                                                  "(docs/results/maze_cpu_accel)"),
    "surrogate.init_first_picks": RemovedKey((0,), f"{_NOT_HELPING} (docs/results/audit_during_training)"),
    "surrogate.target_scaling": RemovedKey(("none",), f"{_NOT_HELPING} (surrogate_accuracy, gym_audit)"),
    "surrogate.validation_fraction": RemovedKey((0.0,), f"{_NOT_HELPING}: early stopping (surrogate_accuracy)"),
    "surrogate.patience": RemovedKey((5,), f"{_NOT_HELPING}: early stopping (surrogate_accuracy)"),
    "surrogate.dilations": RemovedKey(([1, 1], (1, 1)), f"{_NOT_HELPING} (surrogate_accuracy)"),
    "surrogate.betas": RemovedKey(([0.9, 0.999], (0.9, 0.999)), "Adam's betas are the paper's, fixed"),
    "qd.ranker": RemovedKey(("2imp",), "CMA-ME's ranker is the paper's two-stage improvement ranker, fixed"),
    "qd.initial_random_batches": RemovedKey((4,), "MAP-Elites starts with the paper's 4 random batches, fixed: 1 and "
                                                  "2 were no better (docs/DECISIONS.md)"),
    "surrogate.incremental_epochs": RemovedKey((0,), "every training runs surrogate.epochs; shorter later trainings "
                                                     "were never measured to help"),
    # The screen's cost model is the domain's now (the Maze's: the mean path length plus 200).
    "selection.cost_measure": RemovedKey(("", "mean_path_length"), "the screen's cost model is the domain's"),
    "selection.cost_offset": RemovedKey((1.0, 200.0), "the screen's cost model is the domain's"),
    # Settings of how a run is carried out, not of what it computes: any value loads.
    "surrogate.predict_batch_size": RemovedKey((), "fixed (4,096 levels per prediction chunk)"),
    "ray.placement_timeout_s": RemovedKey((), "fixed (120 s)"),
    "image_levels": RemovedKey((), "fixed (4 elite levels per image)"),
    "checkpoint_every": RemovedKey((), "a run checkpoints every outer iteration"),
}


def upgrade_keys(flat: Mapping[str, Any]) -> dict[str, Any]:
    """Dotted keys with renamed keys under their new names and removed keys dropped.

    Raises:
        ConfigError: A removed key holds a value today's code cannot run as it was (the message says why it went).
    """
    upgraded: dict[str, Any] = {}
    for key, value in flat.items():
        removed = REMOVED_KEYS.get(key)
        if removed is None:
            upgraded[RENAMED_KEYS.get(key, key)] = value
        elif removed.accepted and value not in removed.accepted:
            raise ConfigError(f"{key}: this key was removed ({removed.why}); only {shown_value(removed.accepted[0])} "
                              "is what runs now (docs/CONFIG.md)")
    return upgraded


# -------------------------------------------------------------------------------------- variants

#: The DSAGE variants of every domain (its registration adds its QD baselines, e.g. ``map_elites``).
#: Paper variants as data: each is a set of keys, never a code branch.
COMMON_VARIANTS: dict[str, dict[str, Any]] = {
    "dsage": {"surrogate.kind": "two_stage", "selection.method": "downsample"},
    "dsage_only_anc": {"surrogate.kind": "two_stage", "selection.method": "full"},
    # A one-stage model predicts no occupancy, so every measure has its own head.
    "dsage_only_down": {"surrogate.kind": "one_stage", "selection.method": "downsample",
                        "surrogate.occupancy_sum_measure": ""},
    "dsage_basic": {"surrogate.kind": "one_stage", "selection.method": "full", "surrogate.occupancy_sum_measure": ""},
    "dsage_rsample": {"surrogate.kind": "two_stage", "selection.method": "random"},
    # Domain randomisation: the random emitter draws every level from the domain's own generator.
    "dr": {"surrogate.kind": "none", "qd.emitter": "random", "qd.num_emitters": 5, "qd.batch_size": 30,
           "selection.screen_episodes": 0, "selection.screen_gain": False},
}


def presets(domain: str) -> dict[str, dict[str, Any]]:
    """The presets of a registered domain (``paper``, ``tiny``, ...), each a dict of dotted keys."""
    return {name: dict(keys) for name, keys in get_domain(domain).presets.items()}


def variants(domain: str) -> dict[str, dict[str, Any]]:
    """The variants of a registered domain: :data:`COMMON_VARIANTS` plus the domain's own."""
    return {**COMMON_VARIANTS, **{name: dict(keys) for name, keys in get_domain(domain).variants.items()}}


def paper_comparison(domain: str) -> tuple[str, ...]:
    """The variants ``dsage-ray ablate`` compares by default (the paper's Table 2 rows for Maze and Mario)."""
    return tuple(get_domain(domain).comparison)


# ---------------------------------------------------------------------------------------- helpers

def read_config_file(path: str | Path) -> dict[str, Any]:
    """The dotted keys a TOML or JSON config file sets, unvalidated.

    Raises:
        ConfigError: An unreadable file, or one that is not valid TOML/JSON.
    """
    path = Path(path)
    try:
        text = path.read_text()
    except OSError as exc:
        raise ConfigError(f"cannot read config file {path}: {exc.strerror}") from None
    try:
        data = json.loads(text) if path.suffix == ".json" else tomllib.loads(text)
    except (tomllib.TOMLDecodeError, json.JSONDecodeError) as exc:
        raise ConfigError(f"{path}: not valid {'JSON' if path.suffix == '.json' else 'TOML'}: {exc}") from None
    return flatten(data)


def resumed_config(asked: "RunConfig", stored: "RunConfig", *, given: Collection[str]) -> "RunConfig":
    """The config a resumed run continues with: the stored run's, but for the keys the user ``given`` now.

    A default that changed since the run began (a preset's, a variant's, the library's) then leaves the run as it
    began, instead of refusing the resume; a given key that differs from the stored one is still refused when
    the checkpoint loads (:meth:`~dsage_ray.core.runner.DSAGE.load_state_dict` names it), but ``time_budget``.

    Args:
        asked: The config as the resume asked for it (defaults, preset, variant, file and overrides).
        stored: The config the run's checkpoint holds.
        given: The dotted keys the user set (a file's keys, ``--set``, ``--preset``, ...).
    """
    values = stored.to_flat()
    wanted = asked.to_flat()
    values.update({key: wanted[key] for key in given if key in wanted})
    return RunConfig.build(values)


def flatten(values: Mapping[str, Any], prefix: str = "") -> dict[str, Any]:
    """``{"a": {"b": 1}}`` → ``{"a.b": 1}``; already-dotted keys pass through."""
    flat: dict[str, Any] = {}
    for key, value in values.items():
        dotted = f"{prefix}{key}"
        if isinstance(value, Mapping):
            flat.update(flatten(value, dotted + "."))
        else:
            flat[dotted] = value
    return flat


def _get(obj: Any, dotted: str) -> Any:
    for part in dotted.split("."):
        obj = getattr(obj, part)
    return obj


def _assign(config: "RunConfig", flat: Mapping[str, Any]) -> None:
    for dotted, value in flat.items():
        *parents, leaf = dotted.split(".")
        target: Any = config
        for i, part in enumerate(parents):
            target = _subsection(target, part, where=".".join(parents[:i + 1]))
        hints = _keys(target)
        if leaf not in hints or dataclasses.is_dataclass(hints[leaf]):
            raise ConfigError(f"{dotted}: unknown config key ({key_hint(dotted, config.to_flat())})")
        setattr(target, leaf, _coerce(dotted, value, hints[leaf]))


def _keys(section: Any) -> dict[str, Any]:
    """The value keys and sub-sections of a config object (a run config's domains are sections too)."""
    hints = dict(_field_types(type(section))) if dataclasses.is_dataclass(section) else {}
    if isinstance(section, RunConfig):
        del hints["sections"]
    return hints


def _subsection(target: Any, part: str, *, where: str) -> Any:
    """The section ``part`` of ``target``; a registered domain's section is added to a run config on first use."""
    hints = _keys(target)
    if part in hints and dataclasses.is_dataclass(hints[part]):
        return getattr(target, part)
    domains = domain_names() if isinstance(target, RunConfig) else []
    if part in domains:
        return target.section(part)
    sections = [*domains, *(name for name, kind in hints.items() if dataclasses.is_dataclass(kind))]
    raise ConfigError(f"{where}: unknown config section "
                      f"(known: {', '.join(sections) or 'none'}){did_you_mean(part, sections)}")


def key_hint(key: str, known: Mapping[str, Any]) -> str:
    """What to say about an unknown dotted ``key``: the closest known keys, else what there is."""
    close = difflib.get_close_matches(key, list(known), n=3, cutoff=0.6)
    if close:
        return "did you mean " + " or ".join(close) + "?"
    section = key.rsplit(".", 1)[0] + "." if "." in key else ""
    same_section = [k for k in known if section and k.startswith(section)]
    if same_section:
        return "keys of that section: " + ", ".join(same_section)
    return "sections and keys: " + ", ".join(sorted({k.split(".", 1)[0] for k in known}))


def _not_a_choice(key: str, value: Any, choices: tuple[Any, ...]) -> str:
    listed = ", ".join(map(repr, choices[:-1])) + f" or {choices[-1]!r}" if len(choices) > 1 else repr(choices[0])
    return f"{key}: must be {listed} (got {value!r}{did_you_mean(value, choices)})"


def _check_choices(config: Any, prefix: str = "") -> None:
    """Every ``Literal``-typed field holds one of its names (also when set as an attribute, not built)."""
    for name, annotation in _field_types(type(config)).items():
        value = getattr(config, name)
        if dataclasses.is_dataclass(annotation):
            _check_choices(value, f"{prefix}{name}.")
        elif typing.get_origin(annotation) is Literal and value not in typing.get_args(annotation):
            raise ConfigError(_not_a_choice(prefix + name, value, typing.get_args(annotation)))


@functools.cache
def _field_types(cls: type) -> dict[str, Any]:
    return typing.get_type_hints(cls)


def _coerce(key: str, value: Any, annotation: Any) -> Any:
    """Checks ``value`` against a field annotation, converting lists to tuples and ints to floats."""
    if isinstance(value, np.generic):
        value = value.item()
    origin = typing.get_origin(annotation)
    args = typing.get_args(annotation)
    if origin in (typing.Union, types.UnionType):
        for option in args:
            try:
                return _coerce(key, value, option)
            except ConfigError:
                continue
        raise ConfigError(f"{key}: expected {annotation}, got {value!r}")
    if annotation is type(None):
        if value is None:
            return None
        raise ConfigError(f"{key}: expected None, got {value!r}")
    if origin is tuple:
        if not isinstance(value, (list, tuple)):
            raise ConfigError(f"{key}: expected a list, got {value!r}")
        if len(args) == 2 and args[1] is Ellipsis:
            return tuple(_coerce(key, v, args[0]) for v in value)
        if len(args) != len(value):
            raise ConfigError(f"{key}: expected {len(args)} values, got {len(value)}")
        return tuple(_coerce(key, v, a) for v, a in zip(value, args))
    if origin is Literal:
        if value in args:
            return value
        raise ConfigError(_not_a_choice(key, value, args))
    if annotation is bool:
        if isinstance(value, bool):
            return value
        raise ConfigError(f"{key}: expected true/false, got {value!r}")
    if annotation is int:
        if isinstance(value, int) and not isinstance(value, bool):
            return value
        if isinstance(value, float) and value.is_integer():
            return int(value)
        raise ConfigError(f"{key}: expected an integer, got {value!r}")
    if annotation is float:
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            return float(value)
        raise ConfigError(f"{key}: expected a number, got {value!r}")
    if annotation is str:
        if isinstance(value, str):
            return value
        raise ConfigError(f"{key}: expected a string, got {value!r}")
    return value


def shown_value(value: Any) -> str:
    """A config value as a message shows it: numbers plainly (600, not 600.0), the rest as JSON."""
    is_number = isinstance(value, (int, float)) and not isinstance(value, bool)
    return f"{value:g}" if is_number else json.dumps(value)


def changed_keys(stored: "RunConfig", asked: "RunConfig") -> list[str]:
    """``key = stored, not asked`` for each dotted key whose value differs between two configs."""
    before, after = stored.to_flat(), asked.to_flat()
    return [f"{key} = {shown_value(before.get(key))}, not {shown_value(after.get(key))}"
            for key in sorted(before.keys() | after.keys()) if before.get(key) != after.get(key)]


def parse_override(text: str) -> tuple[str, Any]:
    """Parses ``key=value`` from the command line; the value is read as TOML, else kept as a string."""
    if "=" not in text:
        raise ConfigError(f"--set {text!r}: expected key=value")
    key, raw = (part.strip() for part in text.split("=", 1))
    try:
        value = tomllib.loads(f"v = {raw}")["v"]
    except tomllib.TOMLDecodeError:
        value = raw
    return key, value
