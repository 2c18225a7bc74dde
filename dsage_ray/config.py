"""One typed, serialisable config object per run.

A :class:`RunConfig` is a tree of dataclasses. Its flat form uses dotted keys
(``"surrogate.epochs"``), which map 1:1 onto ``tune.grid_search`` axes and ``--set`` overrides.

Resolution order when building a config: dataclass defaults → the domain's *preset* → the
*variant* → explicit keys. ``preset`` and ``variant`` are ordinary fields, so a Tune grid over
``variant`` is an ablation grid.
"""

from __future__ import annotations

import dataclasses
import difflib
import json
import tomllib
import types
import typing
from pathlib import Path
from typing import Any, Literal, Mapping

import numpy as np

from dsage_ray.errors import InputError


class ConfigError(InputError):
    """An invalid config; the message names the offending key."""


# The closed sets of names a config value picks from. Each is the key set of the table that
# implements the names (checked equal in tests/test_config.py); the tables live with their code,
# which imports pyribs or the simulators, so config validation can stay import-free.

#: Keys of :data:`dsage_ray.qd.optimizer.EMITTERS`.
EmitterName = Literal["map_elites", "cma_me", "random"]
#: Keys of :data:`dsage_ray.qd.selection.SELECTION_METHODS`.
SelectionMethod = Literal["downsample", "random", "full"]
#: Keys of :data:`dsage_ray.domains.maze.measures.OBJECTIVES`.
MazeObjective = Literal["validity", "failure_rate", "regret", "regression"]
#: Mario's objectives: the A* agent's completion, or ``1 - completion`` (audits).
MarioObjective = Literal["completion", "incompletion"]
#: Surrogate kinds: ancillary occupancy (``two_stage``), without it (``one_stage``), none (plain QD).
SurrogateKind = Literal["two_stage", "one_stage", "none"]
#: Surrogate prediction arithmetic.
Precision = Literal["auto", "fp32", "bf16"]


@dataclasses.dataclass
class MazeConfig:
    """The Maze domain (SPEC §2)."""

    agent: str = "builtin:wall_follower"
    episodes: int = 50
    height: int = 16
    width: int = 16
    see_through_walls: bool = True
    #: ``validity`` (paper), ``failure_rate``, ``regret`` or ``regression`` (audits).
    objective: MazeObjective = "validity"
    #: Reference agent spec of the ``regression`` objective (empty: none), run on the same seeds.
    reference: str = ""
    measures: tuple[str, ...] = ("num_walls", "mean_path_length")
    #: Cells per measure; ``0`` means "one cell per integer value" (the paper's 256×162 uses 256 and 162).
    archive_dims: tuple[int, ...] = (256, 162)
    #: ``()`` means the natural range of each measure.
    measure_ranges: tuple[tuple[float, float], ...] = ()


@dataclasses.dataclass
class MarioConfig:
    """The Mario domain (SPEC §3)."""

    runs: int = 5
    timer: int = 20
    astar_iterations: int = 1000
    episode_timeout_s: float = 60.0
    generator: str = "builtin"
    #: Standard deviation of the random latents (DR's and DSAGE's ``n_rand`` initial ones); the
    #: authors drew them from N(0, 0.2²).
    latent_sigma: float = 0.2
    #: ``completion`` (paper) or ``incompletion`` (1 − completion, audits).
    objective: MarioObjective = "completion"
    measures: tuple[str, ...] = ("sky_tiles", "mean_jumps")
    archive_dims: tuple[int, ...] = (150, 100)
    measure_ranges: tuple[tuple[float, float], ...] = ((0.0, 150.0), (0.0, 100.0))


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


@dataclasses.dataclass
class QDConfig:
    """The QD optimizer used on the surrogate (inner loop) or directly (baselines)."""

    #: ``map_elites`` (discrete bitmaps), ``cma_me`` (continuous latents) or ``random`` (DR).
    emitter: EmitterName = "map_elites"
    num_emitters: int = 5
    batch_size: int = 30
    #: MAP-Elites: cells mutated per offspring; batches of uniform random solutions before mutating.
    mutation_cells: int = 10
    initial_random_batches: int = 4
    #: CMA-ME.
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
    maze: MazeConfig = dataclasses.field(default_factory=MazeConfig)
    mario: MarioConfig = dataclasses.field(default_factory=MarioConfig)
    surrogate: SurrogateConfig = dataclasses.field(default_factory=SurrogateConfig)
    qd: QDConfig = dataclasses.field(default_factory=QDConfig)
    selection: SelectionConfig = dataclasses.field(default_factory=SelectionConfig)
    ray: RayConfig = dataclasses.field(default_factory=RayConfig)

    # ----------------------------------------------------------------------------------- building

    @classmethod
    def build(cls, values: Mapping[str, Any] | None = None, **kwargs: Any) -> "RunConfig":
        """Builds a validated config from flat (dotted) or nested values plus keyword overrides."""
        explicit = flatten(dict(values or {}))
        explicit.update(flatten(kwargs))
        base = cls()
        _assign(base, {k: explicit[k] for k in ("domain", "preset", "variant") if k in explicit})
        layered: dict[str, Any] = {}
        preset_table = PRESETS.get(base.domain, {})
        if base.preset not in preset_table:
            raise ConfigError(f"preset: unknown preset {base.preset!r} for domain {base.domain!r} "
                              f"(known: {sorted(preset_table)}){did_you_mean(base.preset, preset_table)}")
        layered.update(preset_table[base.preset])
        variant_table = VARIANTS.get(base.domain, {})
        if base.variant not in variant_table:
            raise ConfigError(f"variant: unknown variant {base.variant!r} for domain {base.domain!r} "
                              f"(known: {sorted(variant_table)}){did_you_mean(base.variant, variant_table)}")
        layered.update(variant_table[base.variant])
        layered.update(explicit)
        config = cls()
        _assign(config, layered)
        config.validate()
        return config

    @classmethod
    def from_file(cls, path: str | Path, overrides: Mapping[str, Any] | None = None) -> "RunConfig":
        """Reads a TOML or JSON config file, then applies dotted ``overrides``."""
        path = Path(path)
        try:
            text = path.read_text()
        except OSError as exc:
            raise ConfigError(f"cannot read config file {path}: {exc.strerror}") from None
        try:
            data = json.loads(text) if path.suffix == ".json" else tomllib.loads(text)
        except (tomllib.TOMLDecodeError, json.JSONDecodeError) as exc:
            raise ConfigError(f"{path}: not valid {'JSON' if path.suffix == '.json' else 'TOML'}: {exc}") from None
        values = flatten(data)
        values.update(flatten(dict(overrides or {})))
        return cls.build(values)

    def to_dict(self) -> dict[str, Any]:
        """Nested plain-Python form (lists for tuples), JSON/TOML friendly."""
        return json.loads(json.dumps(dataclasses.asdict(self)))

    def to_flat(self) -> dict[str, Any]:
        """Dotted-key form, e.g. for ``tune.Tuner(param_space=...)``."""
        return flatten(self.to_dict())

    def replace(self, **dotted: Any) -> "RunConfig":
        values = self.to_flat()
        values.update({k.replace("__", "."): v for k, v in dotted.items()})
        return RunConfig.build(values)

    # --------------------------------------------------------------------------------- validation

    @property
    def domain_config(self) -> MazeConfig | MarioConfig:
        return getattr(self, self.domain)

    @property
    def uses_surrogate(self) -> bool:
        return self.surrogate.kind != "none"

    def validate(self) -> None:
        """Raises :class:`ConfigError` naming the first key with an impossible value."""
        def need(cond: bool, key: str, why: str) -> None:
            if not cond:
                raise ConfigError(f"{key}: {why} (got {_get(self, key)!r})")

        _check_choices(self)
        need(self.domain in ("maze", "mario"), "domain", "must be 'maze' or 'mario'")
        need(self.budget >= 1, "budget", "must be positive")
        need(self.n_rand >= 1, "n_rand", "must be positive")
        need(self.budget >= self.n_rand or not self.uses_surrogate, "budget",
             f"must be at least n_rand={self.n_rand} (the first outer iteration evaluates n_rand solutions)")
        need(self.checkpoint_every >= 1, "checkpoint_every", "must be positive")
        need(self.image_every >= 1, "image_every", "must be positive")
        need(self.image_levels >= 0, "image_levels", "must be >= 0")
        need(self.torch_threads >= 1, "torch_threads", "must be positive")
        for key in ("epochs", "batch_size", "train_window", "predict_batch_size"):
            need(getattr(self.surrogate, key) >= 1, f"surrogate.{key}", "must be positive")
        need(self.surrogate.lr > 0, "surrogate.lr", "must be positive")
        need(self.surrogate.holdout_levels >= 0, "surrogate.holdout_levels", "must be >= 0 (0: off)")
        for key in ("num_emitters", "batch_size", "exploit_iterations", "mutation_cells"):
            need(getattr(self.qd, key) >= 1, f"qd.{key}", "must be positive")
        need(self.qd.sigma0 > 0, "qd.sigma0", "must be positive")
        need(self.selection.count >= 1, "selection.count", "must be positive")
        need(self.uses_surrogate or not self.selection.skip_filled, "selection.skip_filled",
             "needs a surrogate (surrogate.kind = 'none' selects nothing)")
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
        if isinstance(dom, MazeConfig):
            need(dom.episodes >= 1, "maze.episodes", "must be positive")
            need(dom.height >= 2 and dom.width >= 2, "maze.height", "maze must be at least 2x2")
            need(bool(dom.reference) == (dom.objective == "regression"), "maze.reference",
                 "the 'regression' objective needs a reference agent spec, and only it uses one")
        else:
            need(dom.runs >= 1, "mario.runs", "must be positive")
            need(dom.timer >= 1, "mario.timer", "must be positive")
            need(dom.astar_iterations >= 0, "mario.astar_iterations", "must be >= 0 (0: stock wall-clock timer)")
            need(dom.latent_sigma > 0, "mario.latent_sigma", "must be positive")


# ------------------------------------------------------------------------------- presets, variants

#: Per-domain presets: ``paper`` reproduces the paper's numbers; ``cpu`` finishes well under an hour
#: on 2 cores; ``demo`` is the few-minute run of ``make run``; ``tiny`` is for tests and smoke runs.
PRESETS: dict[str, dict[str, dict[str, Any]]] = {
    "maze": {
        # The paper held no levels out; ``--set surrogate.holdout_levels=100`` adds 0.1% to its budget.
        "paper": {},
        # CPU presets scale the paper's loop down (SPEC §4: one paper inner loop is ~20 minutes of
        # surrogate predictions on 2 cores). A shorter inner loop fills a smaller surrogate archive,
        # so blocks are smaller to keep a useful number of picks per outer iteration, and a smaller
        # batch gives the surrogate enough Adam steps on the few samples it has early on.
        "cpu": {
            "budget": 2_000,
            "n_rand": 100,
            "maze.episodes": 50,
            "surrogate.epochs": 10,
            "surrogate.batch_size": 16,
            "surrogate.train_window": 1_000,
            "qd.exploit_iterations": 300,
            "selection.block": (4, 3),
            "selection.count": 100,
            # 100 held-out evaluations outside the budget: +5% evaluations.
            "surrogate.holdout_levels": 100,
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
    },
    "mario": {
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
    },
}

_COMMON_VARIANTS: dict[str, dict[str, Any]] = {
    "dsage": {"surrogate.kind": "two_stage", "selection.method": "downsample"},
    "dsage_only_anc": {"surrogate.kind": "two_stage", "selection.method": "full"},
    "dsage_only_down": {"surrogate.kind": "one_stage", "selection.method": "downsample"},
    "dsage_basic": {"surrogate.kind": "one_stage", "selection.method": "full"},
    "dsage_rsample": {"surrogate.kind": "two_stage", "selection.method": "random"},
    # Not in the paper: DSAGE that spends no evaluation on a pick the ground-truth archive already
    # beats (predicted cell occupied with an objective >= the predicted one).
    "dsage_novel": {"surrogate.kind": "two_stage", "selection.method": "downsample", "selection.skip_filled": True},
}

#: Paper variants as data: each is a set of keys, never a code branch.
VARIANTS: dict[str, dict[str, dict[str, Any]]] = {
    "maze": {
        **_COMMON_VARIANTS,
        "map_elites": {"surrogate.kind": "none", "qd.emitter": "map_elites", "qd.num_emitters": 5, "qd.batch_size": 30},
        "dr": {"surrogate.kind": "none", "qd.emitter": "random", "qd.num_emitters": 5, "qd.batch_size": 30},
    },
    "mario": {
        **_COMMON_VARIANTS,
        "cma_me": {"surrogate.kind": "none", "qd.emitter": "cma_me", "qd.num_emitters": 5, "qd.batch_size": 30},
        "dr": {"surrogate.kind": "none", "qd.emitter": "random", "qd.num_emitters": 5, "qd.batch_size": 30},
    },
}


#: The paper's comparison per domain (its Table 2 rows; ``dsage_rsample`` is the appendix ablation).
PAPER_COMPARISON: dict[str, tuple[str, ...]] = {
    "maze": ("dsage", "dsage_only_anc", "dsage_only_down", "dsage_basic", "map_elites", "dr"),
    "mario": ("dsage", "dsage_only_anc", "dsage_only_down", "dsage_basic", "cma_me", "dr"),
}


# ---------------------------------------------------------------------------------------- helpers

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


def _assign(config: Any, flat: Mapping[str, Any]) -> None:
    for dotted, value in flat.items():
        *parents, leaf = dotted.split(".")
        target = config
        for i, part in enumerate(parents):
            if not dataclasses.is_dataclass(target) or part not in _field_types(type(target)):
                sections = [name for name, kind in _field_types(type(target)).items()
                            if dataclasses.is_dataclass(kind)] if dataclasses.is_dataclass(target) else []
                raise ConfigError(f"{'.'.join(parents[:i + 1])}: unknown config section "
                                  f"(known: {', '.join(sections) or 'none'}){did_you_mean(part, sections)}")
            target = getattr(target, part)
        hints = _field_types(type(target)) if dataclasses.is_dataclass(target) else {}
        if leaf not in hints or dataclasses.is_dataclass(hints[leaf]):
            raise ConfigError(f"{dotted}: unknown config key ({key_hint(dotted, RunConfig().to_flat())})")
        setattr(target, leaf, _coerce(dotted, value, hints[leaf]))


def did_you_mean(name: Any, known: Any) -> str:
    """``"; did you mean 'X'?"`` for the closest of ``known`` to ``name``, or ``""``."""
    close = difflib.get_close_matches(str(name), [str(k) for k in known], n=1, cutoff=0.6)
    return f"; did you mean {close[0]!r}?" if close else ""


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
