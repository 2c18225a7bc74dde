"""A Gymnasium environment's parameter space: what a level is, what is measured, and what success means.

A *level* is one value per named parameter. The space declares each parameter's range and where the
environment takes it, the measures (episode statistics, ``info`` keys, observation entries or the parameters
themselves), the success test and, optionally, two state coordinates whose visitation histogram is the
surrogate's ancillary target (the paper's occupancy). It comes from a TOML file (:func:`load_space_file`), a
shipped name (``cartpole``, ``lunarlander``) or command-line strings (:func:`parse_param`,
:func:`parse_env_arg`), and is plain data: reading it runs no code, and its expressions are bounded
(:mod:`~dsage_ray.domains.gym.expressions`). The one exception is ``[env] setup = "python:FILE.py:FUNCTION"``: a
space naming a setup hook runs that code when it plays a level (never when it is read).

A space file::

    [env]
    id = "LunarLander-v3"
    args = {enable_wind = true}           # fixed gym.make keywords, not searched

    [params.gravity]                      # a gym.make keyword (the default)
    range = [-12.0, -2.0]
    [params.length]
    range = [0.25, 2.0]
    attr = "length"                       # an attribute of env.unwrapped, set after every reset
    [params.initial_angle]
    range = [-0.2, 0.2]
    attr = "state[2]"                     # an element of an array attribute

    [measures.landing_x]
    obs = 0                               # observation entry 0 ...
    at = "end"                            # ... at the episode's end ("mean": over the episode)
    range = [-1.0, 1.0]
    [measures.length]                     # episode statistics: return, length, terminated, truncated
    range = [0, 1000]

    [measures.contact_x]                  # a value at an event: obs[0] at the first step where a leg touches,
    obs = 0                               # ... else (it never does) at the end ("mean", "min", "max" or a number)
    at = "first"
    when = "obs[6] > 0 or obs[7] > 0"
    otherwise = "end"
    range = [-1.0, 1.0]

    [success]
    return_at_least = 200.0               # or: info = "is_success"; or a [fault] table instead (fault.py)

    [occupancy]                           # optional: the two-stage surrogate's visitation histogram
    x = {obs = 0, range = [-1.5, 1.5]}
    y = {obs = 1, range = [-0.5, 2.0]}

    [audit]
    measures = ["landing_x", "length"]    # the default audit's archive measures

    [nominal]                             # optional: the level the agent was trained on, played before a search
    gravity = -10.0                       # (default: the environment as registered, no parameter set)

Solutions are points of ``[-1, 1]^P`` (one coordinate per parameter, in declaration order): the box's centre is
every range's midpoint, so CMA-ME's search from the origin starts in the middle of the space.
"""

from __future__ import annotations

import math
import tomllib
from pathlib import Path
from typing import Any, Mapping, Sequence

from dsage_ray.domains.gym.errors import SpaceError
from dsage_ray.domains.gym.expressions import (ExpressionError, check_expression, evaluate_expression,
                                               parse_condition)
from dsage_ray.domains.gym.fault import Fault, parse_fault
from dsage_ray.domains.gym.space_model import (DEFAULT_BINS, DEFAULT_CELLS, EPISODE_STATISTICS, READINGS,
                                               STEP_NAMES, TARGETS, Coordinate, EnvSpace, Measure, Parameter,
                                               Signal, Success, Target)
from dsage_ray.errors import did_you_mean

# The model's names stay importable from here, where the gym domain and its users have always found them.
__all__ = ["DEFAULT_BINS", "DEFAULT_CELLS", "EPISODE_STATISTICS", "READINGS", "STEP_NAMES", "TARGETS", "Coordinate",
           "EnvSpace", "ExpressionError", "Fault", "Measure", "Parameter", "Signal", "SpaceError", "Success", "Target",
           "build_space", "check_expression", "evaluate_expression", "load_space", "merge_space_lines", "parse_env_arg",
           "parse_param", "parse_range", "read_space_tables", "shipped_spaces"]

#: Spaces shipped with the package, by name (``--space cartpole``).
SHIPPED_DIR = Path(__file__).resolve().parent / "spaces"
# Bounds on what a space file may ask for, so that a file received from someone else cannot make the audit allocate
# the machine's memory away or play one episode for ever (each well past any published task's: 50 cells a measure,
# 16 bins, 108,000 steps for Atari).
MAX_CELLS = 1_000
MAX_BINS = 256
MAX_EPISODE_STEPS = 1_000_000
#: The ``python:`` prefix of a setup hook, as of a ``python:`` agent.
SETUP_PREFIX = "python:"


# ------------------------------------------------------------------------------------------ reading


def shipped_spaces() -> list[str]:
    """Names of the spaces shipped with the package (``--space NAME``)."""
    return sorted(p.stem for p in SHIPPED_DIR.glob("*.toml"))


def read_space_tables(space: str) -> tuple[dict[str, Any], str]:
    """The TOML tables of a space file path or a shipped space's name, and where they came from.

    Raises:
        SpaceError: No such file or shipped space, or not TOML.
    """
    path = Path(space).expanduser()
    if not path.is_file() and "/" not in space and not space.endswith(".toml"):
        shipped = SHIPPED_DIR / f"{space}.toml"
        if not shipped.is_file():
            raise SpaceError(f"space {space!r}: no such file, and not a shipped space (shipped: "
                             f"{', '.join(shipped_spaces())})" + did_you_mean(space, shipped_spaces()))
        path = shipped
    if not path.is_file():
        raise SpaceError(f"space file {str(path)!r}: not found")
    try:
        return tomllib.loads(path.read_text()), str(path)
    except (ValueError, UnicodeDecodeError) as exc:  # a TOMLDecodeError, or an integer of over 4300 digits
        raise SpaceError(f"space file {str(path)!r}: not TOML ({exc})") from None


def parse_range(name: str, text: str) -> dict[str, Any]:
    """A ``--param`` range: ``LOW:HIGH`` (float), ``LOW:HIGH:int`` or ``A|B|C`` (choices), as a space file entry.

    Raises:
        SpaceError: Any other form.
    """
    if "|" in text:
        return {"choices": [_scalar(part) for part in text.split("|")]}
    parts = text.split(":")
    if len(parts) in (2, 3) and (len(parts) == 2 or parts[2] in ("int", "float")):
        try:
            low, high = float(parts[0]), float(parts[1])
        except ValueError:
            pass
        else:
            entry: dict[str, Any] = {"range": [low, high]}
            if len(parts) == 3 and parts[2] == "int":
                entry["int"] = True
            return entry
    raise SpaceError(f"--param {name}={text}: expected LOW:HIGH, LOW:HIGH:int or A|B|C")


def parse_param(text: str) -> tuple[str, dict[str, Any]]:
    """A ``--param`` string as ``(name, space file entry)``.

    Forms: ``NAME=RANGE`` (a ``gym.make`` keyword), ``attr.NAME=RANGE`` or ``attr.NAME[I]=RANGE`` (an attribute of
    ``env.unwrapped`` after reset), ``reset.NAME=RANGE`` (a reset option), ``make.NAME=RANGE``; RANGE as in
    :func:`parse_range`.
    """
    name, eq, text_range = text.partition("=")
    name = name.strip()
    if not eq or not name:
        raise SpaceError(f"--param {text!r}: expected NAME=LOW:HIGH (or attr.NAME=..., reset.NAME=...)")
    target, dot, key = name.partition(".")
    entry = parse_range(name, text_range.strip())
    if dot and target in TARGETS:
        entry[target] = True if target == "setup" else key
        return key, entry
    return name, entry


def parse_env_arg(text: str) -> tuple[str, Any]:
    """An ``--env-arg KEY=VALUE`` (the value read as TOML: ``true``, ``3``, ``"x"``; else kept as text)."""
    key, eq, raw = text.partition("=")
    if not eq or not key.strip():
        raise SpaceError(f"--env-arg {text!r}: expected KEY=VALUE")
    return key.strip(), _scalar(raw.strip())


def _scalar(raw: str) -> Any:
    try:
        return tomllib.loads(f"v = {raw}")["v"]
    except tomllib.TOMLDecodeError:
        return raw


def build_space(tables: Mapping[str, Any] | None = None, *, env_id: str = "", params: Sequence[str] = (),
                env_args: Sequence[str] = (), source: str = "command line") -> EnvSpace:
    """The space of a space file's tables, with the command line's environment, parameters and keywords over it.

    Args:
        tables: A space file's tables (:func:`read_space_tables`), or None.
        env_id: Overrides ``[env] id``.
        params: ``--param`` strings (:func:`parse_param`); a name the file declares is replaced.
        env_args: ``--env-arg`` strings (:func:`parse_env_arg`), over ``[env] args``.
        source: Where ``tables`` came from, for messages.

    Raises:
        SpaceError: Anything malformed, named by its table and key.
    """
    tables = dict(tables or {})
    unknown = sorted(set(tables) - {"env", "params", "measures", "success", "fault", "occupancy", "audit", "nominal"})
    if unknown:
        raise SpaceError(f"{source}: unknown table(s) {', '.join(unknown)} (known: env, params, measures, success, "
                         f"fault, occupancy, audit, nominal)")
    env = _table(tables, "env", source)
    _known_keys(env, ("id", "args", "derived", "observation_attr", "max_episode_steps", "setup", "deterministic",
                      "reset_seed"), f"{source} [env]")
    env_id = env_id or str(env.get("id", ""))
    if not env_id:
        raise SpaceError(f"{source}: no environment id (give --env ID or [env] id in a space file)")
    args = dict(_table(env, "args", f"{source} [env]"))
    args.update(parse_env_arg(a) for a in env_args)
    declared = {name: (entry, source) for name, entry in _table(tables, "params", source).items()}
    declared.update((name, (entry, f"--param {text}")) for text in params for name, entry in [parse_param(text)])
    if not declared:
        raise SpaceError(f"{source}: no parameters to search (declare [params.NAME] tables or give --param NAME=LOW:HIGH)")
    parameters = tuple(_parameter(name, entry, where) for name, (entry, where) in declared.items())
    steps = env.get("max_episode_steps")
    if steps is not None and (isinstance(steps, bool) or not isinstance(steps, int)
                              or not 1 <= steps <= MAX_EPISODE_STEPS):
        raise SpaceError(f"{source} [env] max_episode_steps: must be an integer in [1, {MAX_EPISODE_STEPS:,}], "
                         f"got {steps!r}")
    measures = {name: _measure(name, entry, source, parameters, steps)
                for name, entry in _table(tables, "measures", source).items()}
    # Every parameter is also a measure (param.NAME), without declaring it.
    for p in parameters:
        measures.setdefault(f"param.{p.name}", Measure(name=f"param.{p.name}", signal=Signal(source="param", key=p.name),
                                                       low=p.low, high=p.high))
    for name in EPISODE_STATISTICS[2:]:
        measures.setdefault(name, Measure(name=name, signal=Signal(source=name), low=0.0, high=1.0))
    # A fault replaces the success test: a space file can then leave [success] out, and a --space-set fault
    # over a shipped space's [success] needs no way to delete it.
    fault = parse_fault(tables["fault"], where=f"{source} [fault]") if "fault" in tables else None
    success = (_success(_table(tables, "success", source), source) if fault is None or "success" in tables
               else Success(return_at_least=0.0))
    occupancy_table = dict(_table(tables, "occupancy", source))
    bins = occupancy_table.pop("bins", [DEFAULT_BINS, DEFAULT_BINS])
    if not (isinstance(bins, list) and len(bins) == 2
            and all(isinstance(b, int) and not isinstance(b, bool) and 1 <= b <= MAX_BINS for b in bins)):
        raise SpaceError(f"{source} [occupancy] bins: expected two integers in [1, {MAX_BINS}], got {bins!r}")
    if occupancy_table and set(occupancy_table) != {"x", "y"}:
        raise SpaceError(f"{source} [occupancy]: declare exactly x and y (and bins), got {', '.join(occupancy_table)}")
    occupancy = tuple(_coordinate(axis, occupancy_table[axis], source) for axis in "xy") if occupancy_table else ()
    audit = _table(tables, "audit", source)
    audit_measures = tuple(audit.get("measures", ()))
    for name in audit_measures:
        if name not in measures:
            raise SpaceError(f"{source} [audit] measures: unknown measure {name!r} (declared: {', '.join(measures)})")
    derived = dict(_table(env, "derived", f"{source} [env]"))
    for name, expression in derived.items():
        check_expression(expression, where=f"{source} [env.derived] {name}")
    setup = _setup(env.get("setup", ""), f"{source} [env] setup")
    hooked = [p.name for p in parameters if p.target == "setup"]
    if hooked and not setup:
        raise SpaceError(f"{source}: parameter(s) {', '.join(hooked)} go to the setup hook (setup = true), but [env] "
                         f"names none (setup = \"python:FILE.py:FUNCTION\")")
    for p in parameters:
        if p.target == "attr" and p.key in derived:
            raise SpaceError(f"{source}: parameter {p.name!r} sets {p.key!r}, which [env.derived] also computes")
    deterministic = env.get("deterministic", False)
    if not isinstance(deterministic, bool):
        raise SpaceError(f"{source} [env] deterministic: must be true or false, got {deterministic!r}")
    reset_seed = env.get("reset_seed")
    if reset_seed is not None and (isinstance(reset_seed, bool) or not isinstance(reset_seed, int)
                                   or not 0 <= reset_seed < 2**63):
        raise SpaceError(f"{source} [env] reset_seed: must be a non-negative integer, got {reset_seed!r}")
    return EnvSpace(env_id=env_id, env_args=args, params=parameters, measures=measures, success=success,
                    occupancy=occupancy, bins=tuple(bins), derived=derived,
                    observation_attr=str(env.get("observation_attr", "")), max_episode_steps=steps,
                    setup=setup, fault=fault,
                    deterministic=deterministic, reset_seed=reset_seed,
                    nominal=_nominal(_table(tables, "nominal", source), parameters, source),
                    audit_measures=audit_measures, source=source)


def _nominal(table: Mapping[str, Any], params: Sequence[Parameter], source: str) -> dict[str, Any]:
    """The ``[nominal]`` table checked: every name a parameter of the space, every value in its range."""
    by_name = {p.name: p for p in params}
    for name, value in table.items():
        if name not in by_name:
            raise SpaceError(f"{source} [nominal] {name}: not a parameter of the space (its parameters: "
                             f"{', '.join(by_name)})" + did_you_mean(name, list(by_name)))
        try:
            by_name[name].unit(value)
        except SpaceError as exc:
            raise SpaceError(f"{source} [nominal] {name}: {exc}") from None
    return dict(table)


def _setup(spec: Any, where: str) -> str:
    """A setup hook's spec, checked for its form only: reading a space imports nothing."""
    if spec == "":
        return ""
    location, sep, function = spec[len(SETUP_PREFIX):].rpartition(":") if isinstance(spec, str) else ("", "", "")
    if not (isinstance(spec, str) and spec.startswith(SETUP_PREFIX) and sep and location and function.isidentifier()):
        raise SpaceError(f"{where}: expected \"python:FILE.py:FUNCTION\" or \"python:MODULE:FUNCTION\", got {spec!r}")
    return spec


def _table(tables: Mapping[str, Any], name: str, source: str) -> Mapping[str, Any]:
    table = tables.get(name, {})
    if not isinstance(table, Mapping):
        raise SpaceError(f"{source}: {name} must be a table, got {table!r}")
    return table


def _known_keys(entry: Mapping[str, Any], known: Sequence[str], where: str) -> None:
    unknown = sorted(set(entry) - set(known))
    if unknown:
        raise SpaceError(f"{where}: unknown key(s) {', '.join(unknown)} (known: {', '.join(known)})"
                         + did_you_mean(unknown[0], list(known)))


def _pair(value: Any, where: str) -> tuple[float, float]:
    if not (isinstance(value, list) and len(value) == 2
            and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in value)):
        raise SpaceError(f"{where}: range must be [LOW, HIGH], got {value!r}")
    low, high = float(value[0]), float(value[1])
    if not low < high:
        raise SpaceError(f"{where}: range [{low:g}, {high:g}] needs low < high")
    return low, high


def _parameter(name: str, entry: Any, source: str) -> Parameter:
    where = source if source.startswith("--param") else f"{source} [params.{name}]"
    if not isinstance(entry, Mapping):
        raise SpaceError(f"{where}: expected a table with range = [LOW, HIGH] or choices = [...]")
    _known_keys(entry, ("range", "int", "choices", *TARGETS), where)
    targets = [t for t in TARGETS if t in entry]
    if len(targets) > 1:
        raise SpaceError(f"{where}: give one of make, reset, attr, setup, not {' and '.join(targets)}")
    target = targets[0] if targets else "make"
    if target == "setup" and entry["setup"] is not True:
        raise SpaceError(f"{where}: setup = true sends the parameter to the setup hook only, got {entry['setup']!r}")
    key = name if target == "setup" else str(entry.get(target, name))
    if "choices" in entry:
        if "range" in entry:
            raise SpaceError(f"{where}: give range or choices, not both")
        choices = entry["choices"]
        if not isinstance(choices, list):
            raise SpaceError(f"{where}: choices must be a list")
        if len(set(map(repr, choices))) != len(choices):
            raise SpaceError(f"{where}: choices repeat a value: {choices}")
        return Parameter(name=name, target=target, key=key, kind="choice", choices=tuple(choices))
    if "range" not in entry:
        raise SpaceError(f"{where}: needs range = [LOW, HIGH] or choices = [...]")
    low, high = _pair(entry["range"], where)
    integer = entry.get("int", False)
    if not isinstance(integer, bool):
        raise SpaceError(f"{where}: int must be true or false")
    if integer and (low != int(low) or high != int(high)):
        raise SpaceError(f"{where}: an integer range needs integer bounds, got [{low:g}, {high:g}]")
    return Parameter(name=name, target=target, key=key, kind="int" if integer else "float", low=low, high=high)


def _signal(entry: Mapping[str, Any], where: str, *, name: str = "") -> Signal:
    sources = [s for s in ("stat", "info", "obs", "param") if s in entry]
    if len(sources) > 1:
        raise SpaceError(f"{where}: give one of stat, info, obs, param, not {' and '.join(sources)}")
    at = entry.get("at", "end")
    if at not in READINGS:
        raise SpaceError(f"{where}: at must be one of {', '.join(map(repr, READINGS))}, got {at!r}")
    when, otherwise = _event(entry, at, where)
    if not sources:
        if name in EPISODE_STATISTICS:
            return Signal(source=name)
        raise SpaceError(f"{where}: say what it reads: stat = one of {', '.join(EPISODE_STATISTICS)}, info = KEY, "
                         f"obs = INDEX or param = NAME (or name the measure after an episode statistic)")
    source = sources[0]
    value = entry[source]
    if source == "stat":
        if value not in EPISODE_STATISTICS:
            raise SpaceError(f"{where}: stat must be one of {', '.join(EPISODE_STATISTICS)}, got {value!r}")
        return Signal(source=value)
    if source == "obs" and (isinstance(value, bool) or not isinstance(value, int) or value < 0):
        raise SpaceError(f"{where}: obs must be a non-negative index, got {value!r}")
    if source in ("info", "param") and not (isinstance(value, str) and value):
        raise SpaceError(f"{where}: {source} must name a key, got {value!r}")
    if source == "param" and ("at" in entry or when):
        raise SpaceError(f"{where}: a parameter is known before the episode: no at, when or otherwise")
    return Signal(source=source, key=str(value), at=at, when=when, otherwise=otherwise)


def _event(entry: Mapping[str, Any], at: str, where: str) -> tuple[str, str | float]:
    """``at = "first"``'s ``when`` condition and ``otherwise`` fallback, checked (both only with it)."""
    if at != "first":
        if "when" in entry or "otherwise" in entry:
            raise SpaceError(f"{where}: when and otherwise go with at = \"first\" (the first step where WHEN holds)")
        return "", ""
    if "when" not in entry or "otherwise" not in entry:
        raise SpaceError(f"{where}: at = \"first\" needs when = \"CONDITION\" (e.g. \"obs[6] > 0\") and otherwise "
                         f"(the value when it never holds: \"end\", \"mean\", \"min\", \"max\" or a number)")
    parse_condition(entry["when"], where=f"{where} when", names=STEP_NAMES)
    otherwise = entry["otherwise"]
    if isinstance(otherwise, bool) or not (otherwise in READINGS[:-1] or isinstance(otherwise, (int, float))):
        raise SpaceError(f"{where}: otherwise must be \"end\", \"mean\", \"min\", \"max\" or a number, "
                         f"got {otherwise!r}")
    if isinstance(otherwise, (int, float)) and not math.isfinite(otherwise):
        raise SpaceError(f"{where}: otherwise must be a finite number, got {otherwise!r}")
    return entry["when"], float(otherwise) if isinstance(otherwise, (int, float)) else otherwise


def _measure(name: str, entry: Any, source: str, params: Sequence[Parameter], steps: int | None) -> Measure:
    where = f"{source} [measures.{name}]"
    if not isinstance(entry, Mapping):
        raise SpaceError(f"{where}: expected a table")
    _known_keys(entry, ("stat", "info", "obs", "param", "at", "when", "otherwise", "range", "cells"), where)
    signal = _signal(entry, where, name=name)
    if "range" in entry:
        low, high = _pair(entry["range"], where)
    elif signal.source == "param":
        found = [p for p in params if p.name == signal.key]
        if not found:
            raise SpaceError(f"{where}: param {signal.key!r} is not a parameter of the space")
        low, high = found[0].low, found[0].high
    elif signal.source in ("terminated", "truncated"):
        low, high = 0.0, 1.0
    elif signal.source == "length" and steps:
        low, high = 0.0, float(steps)
    else:
        raise SpaceError(f"{where}: needs range = [LOW, HIGH]")
    cells = entry.get("cells", DEFAULT_CELLS)
    if isinstance(cells, bool) or not isinstance(cells, int) or not 1 <= cells <= MAX_CELLS:
        raise SpaceError(f"{where}: cells must be an integer in [1, {MAX_CELLS:,}], got {cells!r}")
    if signal.source == "param" and signal.key not in {p.name for p in params}:
        raise SpaceError(f"{where}: param {signal.key!r} is not a parameter of the space")
    return Measure(name=name, signal=signal, low=low, high=high, cells=cells)


def _coordinate(axis: str, entry: Any, source: str) -> Coordinate:
    where = f"{source} [occupancy.{axis}]"
    if not isinstance(entry, Mapping):
        raise SpaceError(f"{where}: expected a table such as {{obs = 0, range = [-1, 1]}}")
    _known_keys(entry, ("info", "obs", "at", "range", "label"), where)
    if "range" not in entry:
        raise SpaceError(f"{where}: needs range = [LOW, HIGH]")
    signal = _signal(entry, where)
    if signal.source not in ("obs", "info"):
        raise SpaceError(f"{where}: a coordinate is an observation entry (obs = INDEX) or an info key (info = KEY)")
    low, high = _pair(entry["range"], where)
    return Coordinate(signal=signal, low=low, high=high, name=str(entry.get("label", "")))


def _success(entry: Mapping[str, Any], source: str) -> Success:
    where = f"{source} [success]"
    _known_keys(entry, ("info", "return_at_least"), where)
    if ("info" in entry) == ("return_at_least" in entry):
        raise SpaceError(f"{where}: say how an episode succeeds: info = \"is_success\" or return_at_least = NUMBER "
                         f"(one of them)")
    if "info" in entry:
        if not (isinstance(entry["info"], str) and entry["info"]):
            raise SpaceError(f"{where}: info must name a key")
        return Success(info_key=entry["info"])
    threshold = entry["return_at_least"]
    if isinstance(threshold, bool) or not isinstance(threshold, (int, float)):
        raise SpaceError(f"{where}: return_at_least must be a number, got {threshold!r}")
    return Success(return_at_least=float(threshold))


def merge_space_lines(tables: Mapping[str, Any], lines: Sequence[str]) -> dict[str, Any]:
    """``tables`` with each line of a space file (``success.return_at_least = 200``,
    ``measures.speed = {info = "speed", range = [0, 1]}``) set over it, as ``--space-set`` gives them.

    Raises:
        SpaceError: A line that is not one TOML key/value pair.
    """
    merged = _deep_copy(tables)
    for line in lines:
        try:
            update = tomllib.loads(line)
        except ValueError as exc:  # a TOMLDecodeError, or an integer of over 4300 digits
            raise SpaceError(f"--space-set {line!r}: not a line of a space file, KEY = VALUE in TOML ({exc})") from None
        _deep_update(merged, update)
    return merged


def _deep_copy(tables: Mapping[str, Any]) -> dict[str, Any]:
    return {k: _deep_copy(v) if isinstance(v, Mapping) else v for k, v in tables.items()}


def _deep_update(target: dict[str, Any], update: Mapping[str, Any]) -> None:
    for key, value in update.items():
        if isinstance(value, Mapping) and isinstance(target.get(key), Mapping):
            _deep_update(target[key], value)
        else:
            target[key] = _deep_copy(value) if isinstance(value, Mapping) else value


def load_space(config: Any) -> EnvSpace:
    """The space a ``[gym]`` config section describes: its space file (or shipped name), its ``space_set`` lines, then
    its command-line environment id, parameters and keywords over it."""
    tables, source = read_space_tables(config.space) if config.space else ({}, "command line")
    if config.space_set:
        tables = merge_space_lines(tables, config.space_set)
    return build_space(tables, env_id=config.env, params=config.params, env_args=config.env_args, source=source)
