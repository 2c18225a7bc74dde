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
#: How the surrogate scales measure targets (:class:`SurrogateConfig`).
TargetScaling = Literal["none", "range"]


@dataclasses.dataclass
class SurrogateConfig:
    """The deep surrogate model (SPEC §4)."""

    #: ``two_stage`` (ancillary occupancy), ``one_stage`` (no ancillary data) or ``none`` (plain QD).
    kind: SurrogateKind = "two_stage"
    epochs: int = 200
    batch_size: int = 64
    lr: float = 1e-3
    betas: tuple[float, float] = (0.9, 0.999)
    occupancy_weight: float = 10.0
    train_window: int = 20_000
    predict_batch_size: int = 4096
    device: str = "auto"
    #: Prediction arithmetic: ``fp32``, ``bf16`` (the two-stage model's residual blocks, most of its work,
    #: under bf16 autocast) or ``auto`` (bf16 on CUDA and on CPUs with native bf16, else fp32). Training is
    #: always fp32. ``auto`` resolves per machine, as ``device`` does.
    precision: Precision = "auto"
    #: Random valid levels evaluated once, outside the budget, to score the surrogate on levels it
    #: never trains on (``holdout_*`` metrics each outer iteration); 0 turns it off.
    holdout_levels: int = 0
    #: ``none`` (the paper: raw targets) or ``range``: each measure head learns its value mapped from the
    #: domain's measure range onto [0, 1], so every head weighs alike in the loss (raw, a 0-648 path
    #: length outweighs everything else by orders of magnitude). Predictions come back in raw units.
    target_scaling: TargetScaling = "none"
    #: Share of the training window held out each outer iteration for early stopping; 0 (the paper)
    #: trains every ``epochs`` on the whole window.
    validation_fraction: float = 0.0
    #: Early stopping: stop after this many epochs without a lower validation loss and keep the
    #: best epoch's weights (needs ``validation_fraction > 0``).
    patience: int = 5
    #: Name of a measure that equals the sum of the occupancy grid (Maze: ``mean_path_length``, since
    #: the grid counts the agent's steps); a two-stage surrogate then predicts it as the sum of its
    #: predicted occupancy instead of with its own head. Empty (the paper): every measure has a head.
    occupancy_sum_measure: str = ""
    #: Name of a measure the domain has a parameter-free prior for (Maze: ``mean_path_length``, the expected
    #: steps of a uniform random walker from the start to the goal). Its prediction is then the mean of the
    #: network's and the prior's, the prior mapped to the measure by a least-squares line on
    #: ``log(1 + prior)`` fitted to the training window after each training. Empty (the paper): the network alone.
    prior_measure: str = ""
    #: Take the measures (and objective) that are functions of the level alone from the level itself, not from
    #: the network (Maze: ``num_walls``, ``optimal_path_length`` and the ``validity`` objective; Mario: ``sky_tiles``),
    #: through the domain's ``level_values``. The network still trains on them. Off (the paper): everything is
    #: predicted, so a pick can land a few wall counts away from the cell the inner loop chose it for. Maze audits
    #: turn it on (their default measures are both properties of the level).
    exact_level_values: bool = False
    #: Width of the networks (the first convolution of both predictors); 64 is the paper's. The residual
    #: blocks' cost grows as its square (benchmarks/bench_surrogate.py prints FLOPs and predictions/s).
    channels: int = 64
    #: The occupancy predictor's residual blocks, one per entry, each entry its convolutions' dilation.
    #: ``(1, 1)`` is the paper's (an 11×11 receptive field); ``(1, 2, 4)`` sees 31×31 cells.
    dilations: tuple[int, ...] = (1, 1)
    #: Epochs of every training after the first, which trains ``epochs`` (the weights and Adam state
    #: persist, so later trainings start from a fitted model); 0 (the paper): always ``epochs``.
    incremental_epochs: int = 0
    #: Warm start (beyond the paper): a file of ``dsage-ray surrogate pretrain``, or an earlier surrogate
    #: run, audit or trial folder (or its ``checkpoint.dsage``). Its weights start this run's surrogate and
    #: the first outer iteration exploits them instead of evaluating ``n_rand`` random levels
    #: (:mod:`dsage_ray.core.warm_start`). Empty: a cold start (the paper). Made absolute when the
    #: config is built (Tune trials run in their own folder).
    init: str = ""
    #: With ``init``: its dataset becomes the oldest part of this run's dataset, so it weighs in the first
    #: trainings and leaves the ``train_window`` as this run's evaluations arrive. Off: weights only.
    init_prior: bool = True
    #: With ``init``: the first outer iteration evaluates at most this many of its picks (a random subset,
    #: drawn from the run's rng), so the surrogate retrains on this run's agent after a small batch instead
    #: of spending a large share of the budget on the source's model. 0: every pick.
    init_first_picks: int = 0


@dataclasses.dataclass
class QDConfig:
    """The QD optimizer used on the surrogate (inner loop) or directly (baselines)."""

    #: ``map_elites`` (discrete bitmaps), ``cma_me`` (continuous latents), ``random`` (DR), or for continuous
    #: vectors in a box (the domain's ``solution_bounds``, else [-1, 1]): ``gaussian`` (MAP-Elites with Gaussian
    #: mutation of ``sigma0``), ``halton`` (quasi-random samples) or ``cross_entropy`` (a cross-entropy falsifier).
    emitter: EmitterName = "map_elites"
    num_emitters: int = 5
    batch_size: int = 30
    #: MAP-Elites: cells mutated per offspring; batches of uniform random solutions before mutating.
    mutation_cells: int = 10
    initial_random_batches: int = 4
    #: CMA-ME's initial step size; ``gaussian``'s mutation std.
    sigma0: float = 0.2
    ranker: str = "2imp"
    #: Inner-loop iterations (N_exploit) per outer iteration.
    exploit_iterations: int = 10_000


@dataclasses.dataclass
class SelectionConfig:
    """Which surrogate elites get a real evaluation."""

    #: ``downsample``, ``random`` or ``full``.
    method: SelectionMethod = "downsample"
    #: Downsampling block in archive cells per measure.
    block: tuple[int, ...] = (8, 6)
    #: ``random``: how many elites to pick.
    count: int = 432
    #: Drop picks predicted to land in a ground-truth cell that already holds an objective at least
    #: as high (the ``dsage_novel`` variant; see :func:`dsage_ray.qd.selection.skip_filled`).
    skip_filled: bool = False
    #: In each downsampling block, pick uniformly among the elites predicted to land in a cell the
    #: ground-truth archive does not hold yet, where the block has any (not in the paper). Where the
    #: measures are exact (``surrogate.exact_level_values``, e.g. the default Maze audit), "predicted" is
    #: exact too, and a pick is never spent on a cell the search has already filled while the block has
    #: an empty one.
    prefer_new_cells: bool = False
    #: In each downsampling block, pick the elite expected to add most QD-score, judged by the
    #: surrogate's errors on recent picks, instead of a uniform one (the ``dsage_gain`` variant; see
    #: :mod:`dsage_ray.qd.gain`). The first selection goes by the surrogate's errors on the random first levels.
    expected_gain: bool = False
    #: ``expected_gain``: drop a block's pick expected to add less QD-score than this.
    min_gain: float = 0.0
    #: ``expected_gain`` and ``screen_gain``: how many of the latest evaluated picks' errors are kept.
    gain_window: int = 1000
    #: ``expected_gain`` and ``screen_gain``: how many of them, nearest in predicted (or screened) measures, lend a
    #: candidate their errors.
    gain_neighbours: int = 64
    #: ``expected_gain`` and ``screen_gain``: a measure an evaluation's cost grows with in proportion, one of the
    #: domain's work counts (Maze ``steps``, Mario ``search_iterations``), or ``occupancy``: the occupancy sum (the
    #: agent's time in the level; ``expected_gain`` takes each candidate's own as the two-stage surrogate predicts
    #: it). The gain is then counted per evaluation of average cost ("": every evaluation costs the same).
    cost_measure: str = ""
    #: ``cost_measure``: an evaluation's cost at 0, in that measure's or count's units (must be > 0).
    cost_offset: float = 1.0
    #: Each outer iteration after the first, also evaluate this many mutants of the ground-truth archive's best
    #: elites (``elite_share``), beside the surrogate's picks (not in the paper; :mod:`dsage_ray.qd.mutants`).
    #: The mutation is MAP-Elites' (``qd.mutation_cells``) for bitmaps, Gaussian (``qd.sigma0``, clipped to the
    #: domain's ``solution_bounds``) for the continuous emitters' vectors. An audit's never-solved levels are the
    #: best elites, and a mutant of one is often never solved too, which the surrogate cannot predict within a cell.
    #: 0 (the paper): only the surrogate's picks.
    elite_mutants: int = 0
    #: ``elite_mutants``: the parents are drawn uniformly among this share of the ground-truth elites, the
    #: best by objective (ties with the last one included).
    elite_share: float = 0.05
    #: Before the real evaluation, screen the picks and more candidates with this many episodes each (the domain's
    #: ``screen``: Maze only) and evaluate, up to the selection's size, those whose screened result adds to the
    #: ground truth (not in the paper; :mod:`dsage_ray.qd.screen`). MAP-Elites (``qd.emitter = "map_elites"``
    #: without a surrogate) screens mutants of its elites instead, once its random start-up is over. 0 (the
    #: paper): evaluate the picks as chosen.
    screen_episodes: int = 0
    #: ``screen_episodes``: candidates screened per pick (the picks, then other elites predicted to add), or per
    #: level of a MAP-Elites batch.
    screen_pool: float = 4.0
    #: ``screen_episodes``: the agent's arithmetic in the screen. ``fp32``: the agent as it is evaluated; ``bf16``:
    #: its matrix products in bf16, where the agent has such a copy (``Agent.reduced_precision``: the ``dcd``
    #: agents; others screen as they are); ``auto``: bf16 on a CPU with native bf16 arithmetic, else fp32. A
    #: screen is an estimate, so its actions may differ from the agent's now and then; evaluations always run
    #: the agent as it is.
    screen_precision: Precision = "auto"
    #: ``screen_episodes``: keep the screened candidates expected to add most to the ground truth, judged by the
    #: screen's errors on recently evaluated levels (``gain_window`` of them; each candidate takes the errors of
    #: the ``gain_neighbours`` nearest in screened measures), instead of those whose screened cell alone would add,
    #: in the order screened (not in the paper; :func:`dsage_ray.qd.screen.keep_screened`). With a
    #: ``cost_measure``, by expected gain per expected cost.
    screen_gain: bool = False


@dataclasses.dataclass
class RayConfig:
    """How a run uses Ray (ignored by the in-process runner): simulator actors and the trial's resources."""

    #: Simulator actors in the pool (``0``: evaluate in the trial process itself).
    num_workers: int = 2
    #: Logical CPUs each simulator actor reserves (its placement-group bundle).
    cpus_per_worker: float = 0.5
    #: Logical CPUs the trial itself reserves (surrogate training and the inner loop).
    trial_cpus: float = 1.0
    #: Solutions per pool task; 0 (default) picks ~8 chunks per actor per batch, 1 spreads
    #: uneven episodes best, larger amortises Ray's per-task round trip.
    chunk_size: int = 0
    #: Seconds to wait for the simulators' resources before failing instead of hanging.
    placement_timeout_s: float = 120.0


@dataclasses.dataclass
class RunConfig:
    """Everything one DSAGE run needs; serialisable to JSON/TOML and back."""

    name: str = "dsage"
    domain: str = "maze"
    variant: str = "dsage"
    preset: str = "paper"
    seed: int = 0
    #: Total real evaluations.
    budget: int = 100_000
    #: Seconds of wall time the run may spend stepping, cumulative across resumes; 0: no limit. Whichever
    #: of ``budget`` and ``time_budget`` is reached first ends the run at a clean checkpoint; a time budget
    #: that runs out during an evaluation stops the batch there (the levels under way finish). Where a time budget ends a run depends on the machine
    #: and its load, so such a run is not reproducible; an evaluation-budget run is. Raising it and
    #: resuming continues the run (the only key a resume may change).
    time_budget: float = 0.0
    #: Random solutions evaluated in outer iteration 1.
    n_rand: int = 100
    #: Outer iterations between checkpoints / TensorBoard images.
    checkpoint_every: int = 1
    image_every: int = 5
    #: Elite levels (spread along the first measure) rendered to TensorBoard with each heatmap.
    image_levels: int = 4
    #: Torch threads of the process running the outer loop (surrogate training and predictions),
    #: pinned during every outer iteration in every mode (``--local``, a Tune trial, a resumed run).
    #: A float sum split over more threads rounds differently, so the count is part of the run's
    #: config, never taken from the machine. A lone Tune trial may use every CPU of its placement
    #: group: its surrogate phases never overlap its simulators' evaluations.
    torch_threads: int = 1
    #: Pipelined outer loop (DSAGE only): while iteration k's picks are evaluated, the surrogate trains on
    #: the evaluations up to iteration k-1 and picks iteration k+1's levels. With simulators in other
    #: processes (the Ray pool) the two overlap, so the surrogate's time hides behind the simulators'; in
    #: one process they run one after the other. Either way a run computes the same thing, so a seed
    #: gives the same archive in-process and through Tune. The price: each selection is made by a
    #: surrogate one batch behind.
    pipeline: bool = False
    surrogate: SurrogateConfig = dataclasses.field(default_factory=SurrogateConfig)
    qd: QDConfig = dataclasses.field(default_factory=QDConfig)
    selection: SelectionConfig = dataclasses.field(default_factory=SelectionConfig)
    ray: RayConfig = dataclasses.field(default_factory=RayConfig)
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
        explicit = flatten(dict(values or {}))
        explicit.update(flatten(kwargs))
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
        need(self.checkpoint_every >= 1, "checkpoint_every", "must be positive")
        need(self.image_every >= 1, "image_every", "must be positive")
        need(self.image_levels >= 0, "image_levels", "must be >= 0")
        need(self.torch_threads >= 1, "torch_threads", "must be positive")
        for key in ("epochs", "batch_size", "train_window", "predict_batch_size", "channels"):
            need(getattr(self.surrogate, key) >= 1, f"surrogate.{key}", "must be positive")
        need(all(d >= 1 for d in self.surrogate.dilations), "surrogate.dilations", "each dilation must be >= 1")
        need(self.surrogate.incremental_epochs >= 0, "surrogate.incremental_epochs", "must be >= 0 (0: epochs)")
        need(self.surrogate.lr > 0, "surrogate.lr", "must be positive")
        need(self.surrogate.holdout_levels >= 0, "surrogate.holdout_levels", "must be >= 0 (0: off)")
        need(self.surrogate.init_first_picks >= 0, "surrogate.init_first_picks", "must be >= 0 (0: every pick)")
        need(0.0 <= self.surrogate.validation_fraction < 1.0, "surrogate.validation_fraction",
             "must be in [0, 1) (0: no early stopping)")
        need(self.surrogate.patience >= 1, "surrogate.patience", "must be positive")
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
        # Only expected_gain reads the cost model: a run without it may set one its measures lack.
        work_names = [*getattr(self.sections[self.domain], "work_names", ()), OCCUPANCY_COST]
        need(not self.selection.expected_gain or self.selection.cost_measure != OCCUPANCY_COST
             or self.surrogate.kind == "two_stage", "selection.cost_measure",
             "'occupancy' is the two-stage surrogate's predicted occupancy sum; this surrogate predicts none")
        need(not self.selection.expected_gain or not self.selection.cost_measure or measure_names is None
             or self.selection.cost_measure in [*measure_names, *work_names], "selection.cost_measure",
             f"{self.selection.cost_measure!r} is neither one of the measures {list(measure_names or [])} nor one "
             f"of the work counts {work_names}; set it to one an evaluation's cost grows with, or to '' (every "
             "evaluation costs the same)")
        for key in ("num_emitters", "batch_size", "exploit_iterations", "mutation_cells"):
            need(getattr(self.qd, key) >= 1, f"qd.{key}", "must be positive")
        need(self.qd.sigma0 > 0, "qd.sigma0", "must be positive")
        need(self.selection.count >= 1, "selection.count", "must be positive")
        need(self.uses_surrogate or not self.pipeline, "pipeline",
             "pipelines the surrogate's phases with the evaluations; this variant has no surrogate")
        for key in ("skip_filled", "expected_gain", "prefer_new_cells"):
            need(self.uses_surrogate or not getattr(self.selection, key), f"selection.{key}",
                 "needs a surrogate (surrogate.kind = 'none' selects nothing)")
        for key in ("expected_gain", "prefer_new_cells"):
            need(self.selection.method == "downsample" or not getattr(self.selection, key), f"selection.{key}",
                 f"chooses within downsampling blocks; selection.method is {self.selection.method!r}")
        need(not (self.selection.prefer_new_cells and self.selection.expected_gain), "selection.prefer_new_cells",
             "and selection.expected_gain both choose within each block; set one of them")
        need(self.selection.elite_mutants >= 0, "selection.elite_mutants", "must be >= 0 (0: none)")
        need(self.uses_surrogate or not self.selection.elite_mutants, "selection.elite_mutants",
             "adds mutants to a surrogate's picks; this variant's QD search mutates its elites already")
        need(self.mutates_elites or not self.selection.elite_mutants, "selection.elite_mutants",
             f"mutates with qd.emitter's operator; {self.qd.emitter!r} has none (use "
             f"{' or '.join(typing.get_args(MutatingEmitter))})")
        need(0.0 < self.selection.elite_share <= 1.0, "selection.elite_share", "must be in (0, 1]")
        need(self.selection.screen_episodes >= 0, "selection.screen_episodes", "must be >= 0 (0: no screen)")
        need(self.uses_surrogate or self.qd.emitter == "map_elites" or not self.selection.screen_episodes,
             "selection.screen_episodes", f"screens a surrogate's picks, or MAP-Elites' mutants; qd.emitter "
             f"{self.qd.emitter!r} without a surrogate adapts to every level it asked for")
        need(self.selection.screen_pool >= 1, "selection.screen_pool", "must be >= 1 (candidates screened per pick)")
        need(self.selection.screen_episodes > 0 or not self.selection.screen_gain, "selection.screen_gain",
             "ranks screened candidates; set selection.screen_episodes > 0 to screen, or screen_gain = false")
        need(self.selection.min_gain >= 0, "selection.min_gain", "must be >= 0 (0: keep every block's pick)")
        need(self.selection.gain_window >= 1, "selection.gain_window", "must be positive")
        need(self.selection.gain_neighbours >= 1, "selection.gain_neighbours", "must be positive")
        need(self.selection.cost_offset > 0, "selection.cost_offset", "must be positive")
        need(self.ray.num_workers >= 0, "ray.num_workers", "must be >= 0")
        need(self.ray.cpus_per_worker > 0, "ray.cpus_per_worker", "must be positive")
        need(self.ray.trial_cpus > 0, "ray.trial_cpus", "must be positive")
        need(self.ray.chunk_size >= 0, "ray.chunk_size", "must be >= 0 (0: automatic)")
        need(self.ray.placement_timeout_s > 0, "ray.placement_timeout_s", "must be positive")
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


# -------------------------------------------------------------------------------------- variants

#: ``selection.cost_measure`` for a cost read from the surrogate's predicted occupancy sum.
OCCUPANCY_COST = "occupancy"

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
    # Not in the paper: DSAGE that spends no evaluation on a pick the ground-truth archive already
    # beats (predicted cell occupied with an objective >= the predicted one).
    "dsage_novel": {"surrogate.kind": "two_stage", "selection.method": "downsample", "selection.skip_filled": True},
    # Not in the paper: DSAGE that picks, per block, the elite expected to add most QD-score given the
    # surrogate's errors on recent picks, and skips blocks expected to add little.
    "dsage_gain": {"surrogate.kind": "two_stage", "selection.method": "downsample", "selection.expected_gain": True,
                   "selection.min_gain": 0.3},
    # Domain randomisation: the random emitter draws every level from the domain's own generator.
    "dr": {"surrogate.kind": "none", "qd.emitter": "random", "qd.num_emitters": 5, "qd.batch_size": 30},
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
