"""The domain registry: every domain, built in or not, is a :class:`DomainSpec` found by name.

A package makes a domain available by naming its spec in the ``dsage_ray.domains`` entry-point
group of its ``pyproject.toml`` (Maze and Mario do exactly this in dsage_ray's own)::

    [project.entry-points."dsage_ray.domains"]
    gridpath = "dsage_ray_gridpath.plugin:DOMAIN"

Entry points are listed without being imported; a spec is loaded the first time its name is
asked for, so importing dsage_ray imports no simulator (no MiniGrid, no JPype). An entry point is
visible to every process of the environment, Ray's simulator actors included, which is why it is
the way to ship a domain; :func:`register_domain` adds one to the calling process only (tests,
notebooks). See docs/EXTENDING.md.
"""

from __future__ import annotations

import dataclasses
import importlib
import importlib.metadata
from typing import Any, Callable, Mapping, Protocol, runtime_checkable

from dsage_ray.agent_registry import plugin_kinds
from dsage_ray.errors import InputError, did_you_mean
from dsage_ray.plugins import Plugins
from dsage_ray.plugins import scan as scan_plugins

#: The entry-point group a package registers its domains in.
ENTRY_POINT_GROUP = "dsage_ray.domains"
#: The domain a run, an audit or a command uses when none is named.
DEFAULT_DOMAIN = "maze"


def domain_key(default: Any, *, note: str) -> Any:
    """A field of a domain's config section, with the one line ``dsage-ray config`` and docs/CONFIG.md print for it.

    Args:
        default: The default value (a tuple stays immutable; no factory needed).
        note: One line: what the key does.
    """
    return dataclasses.field(default=default, metadata={"note": note})


@dataclasses.dataclass(frozen=True, kw_only=True)
class ReportField:
    """A number the audit report shows: a column of the levels (``AuditSpec.columns``) or a setting of the
    whole collection (``AuditSpec.settings``).

    Attributes:
        key: The key of the collection entry (a column) or of the collection (a setting).
        label: What the report calls it (default: ``key``).
        format: A :meth:`str.format` template of one value, e.g. ``"{:.1f}"`` or ``"{} steps per episode"``
            (default: one format per column, suited to its magnitude).
        tooltip: Explains the number; ``{name}`` is replaced by the collection's key ``name`` (e.g.
            ``{max_steps}``). A tooltip naming a key the collection lacks is left out.
        mean: The name of the column's mean where the report averages it (the region table, ``dsage-ray
            compare``), e.g. ``"mean path length"``; None: not averaged.
    """

    key: str
    label: str = ""
    format: str | None = None
    tooltip: str = ""
    mean: str | None = None

    @property
    def name(self) -> str:
        """The label, or the key when there is none."""
        return self.label or self.key

    def text(self, value: Any) -> str:
        """``value`` in this field's format (empty for None)."""
        return "" if value is None else (self.format or "{}").format(value)

    def explain(self, collection: Mapping[str, Any]) -> str:
        """The tooltip with the collection's keys filled in; empty when it names one the collection lacks."""
        try:
            return self.tooltip.format_map(collection)
        except (KeyError, IndexError, ValueError):
            return ""


@dataclasses.dataclass(frozen=True, kw_only=True)
class AuditFlag:
    """A flag ``dsage-ray audit`` takes for one domain, setting one key of its config section (``--env ID`` is
    ``gym.env``); the audit refuses it for another domain.

    Attributes:
        flag: The flag, e.g. ``"--env"``.
        key: The key of the domain's section it sets, e.g. ``"env"``.
        help: The flag's line of ``dsage-ray audit --help``.
        metavar: The value's name in the help (default: the key in capitals).
        repeat: Whether the flag repeats; its values then set the key as a tuple.
    """

    flag: str
    key: str
    help: str
    metavar: str | None = None
    repeat: bool = False


@dataclasses.dataclass(frozen=True, kw_only=True)
class AgentKinds:
    """The agent specs a domain plays, by kind (a spec is ``KIND`` or ``KIND:TARGET``).

    Attributes:
        forms: Each kind the domain plays and the spec forms it takes, e.g. ``{"astar": "astar[:ITERATIONS]"}``
            or ``{"rllib": "rllib:PATH"}`` (a kind of :mod:`dsage_ray.agent_registry`, loaded by
            :func:`dsage_ray.agents.load_agent` over the domain's spaces).
        loaders: The domain's own kinds' factories, ``{kind: "module:function"}`` (imported only when a spec
            names the kind), which the domain passes to :func:`dsage_ray.agents.load_agent`; for this domain
            one replaces the generic kind of the same name (the Maze's MiniGrid ``torchscript`` convention).
        plugins: Whether the domain also plays the kinds installed packages add (the ``dsage_ray.agents``
            entry-point group) and those registered in this process.
    """

    forms: Mapping[str, str] = dataclasses.field(default_factory=dict)
    loaders: Mapping[str, str] = dataclasses.field(default_factory=dict)
    plugins: bool = False

    def kinds(self) -> dict[str, str]:
        """Every kind the domain plays and its spec form, the plug-in kinds' (imported: none) included."""
        if not self.plugins:
            return dict(self.forms)
        return dict(sorted({**{kind: f"{kind}:PATH" for kind in plugin_kinds()}, **self.forms}.items()))


@dataclasses.dataclass(frozen=True, kw_only=True)
class AuditSpec:
    """What ``dsage-ray audit`` and ``dsage-ray compare`` need to know about a domain before building one
    (and the audit report, which reads a collection without building it).

    Attributes:
        objectives: Objectives an audit may maximise (the first is the default); ``"regression"``
            among them means the domain's audits can search where one agent does worse than another
            (``--reference``).
        measures: Measures of the default audit.
        default_agent: The agent spec audited when none is named.
        episodes_key: The dotted config key of the episodes (or runs) per evaluation.
        columns: The domain's own numbers of a collection entry the report shows, in order (default:
            every numeric one, named by its key); measures are shown as measures.
        settings: The domain's settings of the collection the report's run description shows (Maze:
            its step limit).
        flags: The flags ``dsage-ray audit`` takes for this domain only (the gym domain's ``--env``, ``--param``),
            shown in the help as one group titled ``flags_title``.
        flags_title: The title of :attr:`flags`' group in the help (default: ``--domain NAME``).
        surrogate_keys: Dotted config keys an audit adds when its search is a DSAGE variant whose QD emitter
            mutates (``RunConfig.mutates_elites``), under the user's own keys; other searches leave them out.
        auto_keeps_dsage: Why ``search = "auto"`` keeps DSAGE in this domain's audits (empty: an audit's ``auto``
            chooses as a run's does). ``auto``'s break-even compares a pick's cost with a random level's, measured
            in searches for QD-score; where failures are the slow levels to play (a maze the agent never solves
            runs to the step limit), an audit's picks cost more than that for every search that finds failures,
            and equal-time audits are the measurement that decides.
        summary: A few words after the domain's name in ``--domain``'s help (gym: ``"any Gymnasium environment:
            --env, --space, --param"``).
        nominal: What the domain's nominal level is, in the help of the audit's nominal check (Maze: ``"an open
            room"``).
        episodes_word: What the help calls the episodes of an evaluation (Mario: ``"runs"``).
        objective_notes: A few words on an objective, by name, after it in ``--objective``'s help (Mario:
            ``{"incompletion": "1 - completion"}``).
        measures_note: Said after :attr:`measures` in ``--measures``' help, or in their place when there are none
            (Maze: the paper's other measures; gym: ``"the space's [audit] measures"``).
        examples: Lines of ``dsage-ray audit --help``'s examples, each a command then ``# what it shows``: the
            domain's ``audit`` and ``compare`` commands (the default domain's come first).
    """

    objectives: tuple[str, ...]
    measures: tuple[str, ...]
    default_agent: str
    episodes_key: str
    columns: tuple[ReportField, ...] = ()
    settings: tuple[ReportField, ...] = ()
    flags: tuple[AuditFlag, ...] = ()
    flags_title: str = ""
    surrogate_keys: Mapping[str, Any] = dataclasses.field(default_factory=dict)
    auto_keeps_dsage: str = ""
    summary: str = ""
    nominal: str = ""
    episodes_word: str = "episodes"
    objective_notes: Mapping[str, str] = dataclasses.field(default_factory=dict)
    measures_note: str = ""
    examples: tuple[str, ...] = ()


@dataclasses.dataclass(frozen=True, kw_only=True)
class DomainSpec:
    """A domain's registration record: everything the package reads about it besides the domain object.

    Attributes:
        name: The ``domain`` config value, the config section's name and the entry point's name.
        config: The config section, a dataclass whose fields all have defaults. It must have
            ``measures``, ``archive_dims`` and ``measure_ranges`` (checked generically), and may
            define ``validate(need)`` for its own keys: ``need(condition, key, why)`` with ``key``
            relative to the section (``"episodes"``), and ``complete(run_config, given=keys)``, called once every
            key is assigned and before validation, to fill keys that follow from others and that the caller did
            not give (the gym domain's measures from its space file): :class:`CheckedSection` and
            :class:`CompletingSection`.
        domain: The domain class as ``"module:Class"``, imported only when a domain is built; it is
            called as ``Class(config=section)`` and implements :class:`dsage_ray.types.Domain`.
        presets: Keys per preset name (dotted, over the dataclass defaults); ``tiny`` is the one
            tests and smoke runs use. Must hold ``paper``, the default preset.
        variants: Keys per variant, merged over the DSAGE variants every domain has
            (:data:`dsage_ray.config.COMMON_VARIANTS`): typically the domain's QD baselines.
        comparison: The variants ``dsage-ray ablate`` runs by default.
        direct_search: The variant without a surrogate that ``search = "auto"`` continues with when the surrogate
            costs more than it buys (``""``: none; ``auto`` is then refused).
        screenable: Whether the domain class is a :class:`~dsage_ray.types.ScreenableDomain`, so that the screening
            keys (``selection.screen_episodes``, ``selection.screen_gain``) apply; said here so that a config is
            checked without importing the class (a test holds the two equal for the shipped domains).
        audit: What an audit needs (``None``: the domain cannot be audited).
        agents: The agent specs the domain plays (``None``: its agent is fixed, there is none to name).
        cli: A module with ``add_subparser(subparsers)`` adding ``dsage-ray NAME ...`` commands.
        actor_env: Extra environment variables of a Ray simulator actor (e.g. a preload library),
            computed in the driver when the actor starts.
    """

    name: str
    config: type
    domain: str
    presets: Mapping[str, Mapping[str, Any]]
    variants: Mapping[str, Mapping[str, Any]] = dataclasses.field(default_factory=dict)
    comparison: tuple[str, ...] = ("dsage",)
    direct_search: str = ""
    screenable: bool = False
    audit: AuditSpec | None = None
    agents: AgentKinds | None = None
    cli: str | None = None
    actor_env: Callable[[], dict[str, str]] | None = None

    def __post_init__(self) -> None:
        if not self.name.isidentifier():
            raise InputError(f"domain name {self.name!r} must be a Python identifier (it names a config section)")
        if self.direct_search and self.direct_search not in {*self.variants, "dr"}:
            raise InputError(f"domain {self.name!r}: direct_search {self.direct_search!r} is not one of its variants")
        if not dataclasses.is_dataclass(self.config):
            raise InputError(f"domain {self.name!r}: config must be a dataclass, got {self.config!r}")
        missing = {"measures", "archive_dims", "measure_ranges"} - {f.name for f in dataclasses.fields(self.config)}
        if missing:
            raise InputError(f"domain {self.name!r}: config section {self.config.__name__} lacks {sorted(missing)}")
        if "paper" not in self.presets:
            raise InputError(f"domain {self.name!r}: presets need a 'paper' entry (the default preset)")
        if ":" not in self.domain:
            raise InputError(f"domain {self.name!r}: domain must read 'module:Class', got {self.domain!r}")

    def check_agent(self, spec: str) -> None:
        """Refuses an agent spec of a kind the domain does not play, naming the kinds it does.

        Raises:
            InputError: ``spec``'s kind is not among :attr:`agents` (the message also names the domains
                that play it, if any).
        """
        kinds = self.agents.kinds() if self.agents else {}
        kind = str(spec).strip().partition(":")[0]
        if kind in kinds:
            return
        players = [name for name in domain_names() if name != self.name and kind in _played_kinds(name)]
        elsewhere = f"; {kind!r} agents are played by: {', '.join(players)}" if players else ""
        raise InputError(f"domain {self.name!r} does not play {kind!r} agents (agent spec {spec!r}); its agents: "
                         f"{', '.join(kinds.values()) or 'none to choose'}{elsewhere}")

    def domain_class(self) -> type:
        """Imports and returns the domain class."""
        return _import(self.domain)


@runtime_checkable
class CheckedSection(Protocol):
    """A domain's config section with rules of its own keys, checked after the generic ones."""

    def validate(self, need: Callable[[bool, str, str], None]) -> None:
        """Calls ``need(condition, key, why)`` per rule, ``key`` relative to the section (``"episodes"``)."""


@runtime_checkable
class CompletingSection(Protocol):
    """A domain's config section some of whose keys follow from others (the gym domain's measures from its space
    file), filled in once every key is assigned, before validation."""

    def complete(self, config: Any, *, given: frozenset[str]) -> None:
        """Fills in the section's keys that follow from the run config ``config``'s others.

        Args:
            config: The run config, every key assigned (defaults, preset, variant, then the caller's).
            given: The dotted keys the caller set (``RunConfig.build``'s values): a key filled in here only where
                it is not among them is one the caller can still set to any value, its default included.
        """


def _import(path: str) -> Any:
    """The object a ``"module:name"`` path names, its module imported now."""
    module, _, attribute = path.partition(":")
    return getattr(importlib.import_module(module), attribute)


_registered: dict[str, DomainSpec] = {}
#: The installed domains, read once (and again when a name is missing: a package installed since). Names
#: two packages claim are an error only when the name is used.
_plugins: Plugins | None = None


def register_domain(spec: DomainSpec) -> DomainSpec:
    """Adds ``spec`` to this process's registry and returns it.

    Registering the same spec object again is a no-op (an entry point that also calls this).

    Raises:
        InputError: Another spec already holds the name.
    """
    held = _registered.get(spec.name)
    if held is not None and held is not spec:
        raise InputError(f"domain {spec.name!r} is already registered (config {held.config.__module__}."
                         f"{held.config.__name__}); pick another name")
    _registered[spec.name] = spec
    return spec


def domain_names() -> list[str]:
    """Every domain a config may name: installed entry points (none imported), then ones registered in-process."""
    return list(dict.fromkeys([*_scan(), *_registered]))


def get_domain(name: str) -> DomainSpec:
    """The spec of domain ``name``, loading its entry point on first use.

    Raises:
        InputError: No such domain (the message lists the known ones, with a did-you-mean), or an
            entry point that does not load to a :class:`DomainSpec` of that name.
    """
    if name in _registered:
        return _registered[name]
    points = _scan()
    if name not in points:
        importlib.invalidate_caches()  # a package installed since the last look
        points = _scan(refresh=True)
    if name not in points:
        known = domain_names()
        raise InputError(f"unknown domain {name!r} (known: {', '.join(known) or 'none'})" + did_you_mean(name, known)
                         + ("" if known else f"; is dsage_ray installed (pip install -e .)? Domains are "
                                             f"entry points of the {ENTRY_POINT_GROUP!r} group"))
    if name in _plugins.clashes:
        claims = " and ".join(repr(point.value) for point in _plugins.clashes[name])
        raise InputError(f"domain {name!r} is registered twice: {claims} "
                         f"(two installed packages claim the name; uninstall one)")
    point = points[name]
    try:
        spec = point.load()
    except Exception as exc:  # a plug-in's import error, reported with the plug-in's name
        raise InputError(f"domain {name!r}: cannot load entry point {point.value!r}: {exc}") from exc
    if not isinstance(spec, DomainSpec) or spec.name != name:
        raise InputError(f"domain {name!r}: entry point {point.value!r} must name a DomainSpec with "
                         f"name={name!r}, got {spec!r}")
    return register_domain(spec)


def agent_forms() -> dict[str, list[str]]:
    """The agent spec forms of every domain that plays named agents (a domain that does not load is left out)."""
    return {name: list(kinds.values()) for name in domain_names() if (kinds := _played_kinds(name))}


def _played_kinds(name: str) -> dict[str, str]:
    try:
        agents = get_domain(name).agents
    except InputError:  # a plug-in that does not load plays nothing here
        return {}
    return agents.kinds() if agents else {}


def unregister_domain(name: str) -> None:
    """Forgets ``name`` and re-reads the entry points (tests that install or register a domain clean up with it)."""
    _registered.pop(name, None)
    _scan(refresh=True)


def _scan(*, refresh: bool = False) -> dict[str, importlib.metadata.EntryPoint]:
    global _plugins
    if _plugins is None or refresh:
        _plugins = scan_plugins(ENTRY_POINT_GROUP)
    return _plugins.points
