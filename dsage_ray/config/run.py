"""The run config: a tree of the schema's sections plus the run's domain section, built in layers (dataclass
defaults → the domain's preset → the variant → explicit keys) and validated."""

from __future__ import annotations

import dataclasses
import json
import typing
from pathlib import Path
from typing import Any, Collection, Mapping

from dsage_ray.config import layering
from dsage_ray.config.migration import upgrade_keys
from dsage_ray.config.parsing import coerce, field_types, flatten, key_hint, read_config_file, shown_value
from dsage_ray.config.schema import (ConfigError, ExperimentalConfig, MutatingEmitter, QDConfig, RayConfig,
                                     SearchMode, SelectionConfig, SurrogateConfig, key)
from dsage_ray.config.validation import validate
from dsage_ray.domains.registry import DEFAULT_DOMAIN, CompletingSection, domain_names, get_domain
from dsage_ray.errors import InputError, did_you_mean


@dataclasses.dataclass
class RunConfig:
    """Everything one DSAGE run needs; serialisable to JSON/TOML and back."""

    name: str = key("dsage", status="tool", values="a relative folder name",
                    note="the run's folder under tb_logs/ (or --out)")
    domain: str = key(DEFAULT_DOMAIN, status="tool", values="a registered domain", note="maze, mario, gym, or a plug-in's")
    variant: str = key("dsage", status="paper", values="a variant of the domain",
                       note="the search: dsage, its ablations, or a baseline (sets other keys)")
    #: ``auto``: continue with the domain's direct search (``DomainSpec.direct_search``) on the same archive, with a
    #: time budget right after the random iteration when too few surrogate iterations fit in the time left, else
    #: after DSAGE's first surrogate iteration when a level DSAGE picked cost more than
    #: :data:`~dsage_ray.core.auto_search.BREAK_EVEN_COST_RATIO` times a random one, surrogate time included.
    search: SearchMode = key("fixed", status="opt-in",
                             note="auto: DSAGE, or the domain's direct search where the surrogate costs more than it "
                                  "buys (docs/DECISIONS.md); audits with a time budget and gym [fault] spaces take "
                                  "it unless told")
    preset: str = key("paper", status="tool", values="a preset of the domain",
                      note="the scale: paper, cpu, demo or tiny (sets other keys)")
    seed: int = key(0, status="tool",
                    note="the run's seed; the same seed and config give the same archive (where search = auto "
                         "chose by the clock, the same choice)")
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
            if domain in field_types(RunConfig):
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
        base = cls(**{key: coerce(key, explicit[key], field_types(cls)[key])
                      for key in ("domain", "preset", "variant") if key in explicit})
        layered: dict[str, Any] = {}
        try:
            preset_table = layering.presets(base.domain)
        except InputError as exc:
            raise ConfigError(f"domain: {exc}") from None
        if base.preset not in preset_table:
            raise ConfigError(f"preset: unknown preset {base.preset!r} for domain {base.domain!r} "
                              f"(known: {sorted(preset_table)}){did_you_mean(base.preset, preset_table)}")
        layered.update(preset_table[base.preset])
        variant_table = layering.variants(base.domain)
        if base.variant not in variant_table:
            raise ConfigError(f"variant: unknown variant {base.variant!r} for domain {base.domain!r} "
                              f"(known: {sorted(variant_table)}){did_you_mean(base.variant, variant_table)}")
        layered.update(variant_table[base.variant])
        layered.update(explicit)
        config = cls(domain=base.domain)
        _assign(config, layered)
        # A section whose keys depend on each other fills in what was left to it (the gym domain's measures
        # come from its space file), before validation sees them.
        if isinstance(config.domain_config, CompletingSection):
            config.domain_config.complete(config, given=frozenset(explicit))
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

    def assign(self, values: Mapping[str, Any]) -> None:
        """Sets dotted keys in place, each coerced and its name checked as :meth:`build` does (a completing section
        fills in keys with it); nothing is validated until :meth:`validate`."""
        _assign(self, values)

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
    def can_search_auto(self) -> bool:
        """Whether ``search = "auto"`` can run here: it starts as DSAGE (a surrogate), times an iteration that did not
        overlap the evaluations (no pipeline), and compares with the random first levels (no warm start). What
        :func:`~dsage_ray.config.validation.validate` checks for ``auto``, but the domain's direct search."""
        return self.uses_surrogate and not self.pipeline and not self.surrogate.init

    @property
    def mutates_elites(self) -> bool:
        """A surrogate search whose QD emitter has a mutation: ``selection.elite_mutants`` can apply."""
        return self.uses_surrogate and self.qd.emitter in typing.get_args(MutatingEmitter)

    def validate(self) -> None:
        """Raises :class:`ConfigError` naming the first key with an impossible value
        (:func:`dsage_ray.config.validation.validate`)."""
        validate(self)

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


def _assign(config: "RunConfig", flat: Mapping[str, Any]) -> None:
    for dotted, value in flat.items():
        *parents, leaf = dotted.split(".")
        target: Any = config
        for i, part in enumerate(parents):
            target = _subsection(target, part, where=".".join(parents[:i + 1]))
        hints = _keys(target)
        if leaf not in hints or dataclasses.is_dataclass(hints[leaf]):
            raise ConfigError(f"{dotted}: unknown config key ({key_hint(dotted, config.to_flat())})")
        setattr(target, leaf, coerce(dotted, value, hints[leaf]))


def _keys(section: Any) -> dict[str, Any]:
    """The value keys and sub-sections of a config object (a run config's domains are sections too)."""
    hints = dict(field_types(type(section))) if dataclasses.is_dataclass(section) else {}
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


def changed_keys(stored: "RunConfig", asked: "RunConfig") -> list[str]:
    """``key = stored, not asked`` for each dotted key whose value differs between two configs."""
    before, after = stored.to_flat(), asked.to_flat()
    return [f"{key} = {shown_value(before.get(key))}, not {shown_value(after.get(key))}"
            for key in sorted(before.keys() | after.keys()) if before.get(key) != after.get(key)]
