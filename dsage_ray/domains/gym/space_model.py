"""A gym space's model: parameters, signals, measures, the success test and the whole space, as plain data.

:mod:`dsage_ray.domains.gym.space` reads them from space files and the command line (and re-exports them).
"""

from __future__ import annotations

import dataclasses
import math
import re
from typing import Any, Literal, Mapping

import numpy as np

from dsage_ray.domains.gym.errors import SpaceError
from dsage_ray.domains.gym.fault import Fault
from dsage_ray.errors import did_you_mean

#: Where a parameter goes: a ``gym.make`` keyword, a ``reset(options=...)`` entry, an attribute of
#: ``env.unwrapped`` set after each reset, or only the setup hook (``setup = true``), which gets every value.
Target = Literal["make", "reset", "attr", "setup"]
TARGETS: tuple[str, ...] = ("make", "reset", "attr", "setup")
#: Episode statistics a measure may name directly.
EPISODE_STATISTICS: tuple[str, ...] = ("return", "length", "terminated", "truncated")
#: Default archive cells per measure.
DEFAULT_CELLS = 20
#: Default histogram bins per occupancy coordinate.
DEFAULT_BINS = 8
#: How a signal is read off an episode's steps (``first``: at the first step where its ``when`` holds).
READINGS: tuple[str, ...] = ("end", "mean", "min", "max", "first")
#: The names a measure's ``when`` condition may use, read after each step (``step``: 1 at the first).
STEP_NAMES: tuple[str, ...] = ("obs", "reward", "info", "step")
_ATTRIBUTE = re.compile(r"^([A-Za-z_]\w*)(?:\[(\d+)\])?$")


@dataclasses.dataclass(frozen=True, kw_only=True)
class Parameter:
    """One searched parameter.

    Attributes:
        name: What the level files and the report call it.
        target: Where the environment takes it (:data:`Target`).
        key: The keyword, reset option or attribute (``state[2]``: element 2 of the array attribute ``state``).
        kind: ``float``, ``int`` or ``choice``.
        low, high: The range (``choice``: 0 and the number of choices − 1).
        choices: The values of a ``choice`` parameter.
    """

    name: str
    target: Target = "make"
    key: str = ""
    kind: Literal["float", "int", "choice"] = "float"
    low: float = 0.0
    high: float = 1.0
    choices: tuple[Any, ...] = ()

    def __post_init__(self) -> None:
        if not self.key:
            object.__setattr__(self, "key", self.name)
        if self.target not in TARGETS:
            raise SpaceError(f"parameter {self.name!r}: set = {self.target!r} is not one of {', '.join(TARGETS)}")
        if self.target == "attr" and not _ATTRIBUTE.match(self.key):
            raise SpaceError(f"parameter {self.name!r}: attribute {self.key!r} is not NAME or NAME[INDEX]")
        if self.kind == "choice":
            if len(self.choices) < 2:
                raise SpaceError(f"parameter {self.name!r}: a choice needs at least two values, got {list(self.choices)}")
            object.__setattr__(self, "low", 0.0)
            object.__setattr__(self, "high", float(len(self.choices) - 1))
        elif not (math.isfinite(self.low) and math.isfinite(self.high) and self.low < self.high):
            raise SpaceError(f"parameter {self.name!r}: range [{self.low:g}, {self.high:g}] needs low < high")

    def numbers(self, units: np.ndarray) -> np.ndarray:
        """The parameter as a number at each box coordinate (clipped to ``[-1, 1]``): its value, or a choice's index.

        This is what a ``param.NAME`` measure reads, vectorised for the surrogate's exact values.
        """
        x = self.low + (self.high - self.low) * (np.clip(np.asarray(units, dtype=np.float64), -1.0, 1.0) + 1.0) / 2.0
        return x if self.kind == "float" else np.round(x)

    def value(self, unit: float) -> Any:
        """The parameter's value at box coordinate ``unit`` (clipped to ``[-1, 1]``)."""
        x = float(self.numbers(np.asarray(unit)))
        if self.kind == "float":
            return x
        return self.choices[int(x)] if self.kind == "choice" else int(x)

    def unit(self, value: Any) -> float:
        """The box coordinate of ``value`` (the inverse of :meth:`value`).

        Raises:
            SpaceError: A value outside the range, or not one of the choices.
        """
        if self.kind == "choice":
            if value not in self.choices:
                raise SpaceError(f"parameter {self.name!r}: {value!r} is not one of {list(self.choices)}")
            x = float(self.choices.index(value))
        else:
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise SpaceError(f"parameter {self.name!r}: {value!r} is not a number")
            x = float(value)
            if not self.low - 1e-9 * abs(self.high - self.low) <= x <= self.high + 1e-9 * abs(self.high - self.low):
                raise SpaceError(f"parameter {self.name!r}: {x:g} is outside its range [{self.low:g}, {self.high:g}]")
        return 2.0 * (x - self.low) / (self.high - self.low) - 1.0

    def describe(self) -> str:
        """``name in [low, high] (attribute state[2])``: one line for messages and help."""
        span = "{" + ", ".join(map(str, self.choices)) + "}" if self.kind == "choice" else (
            f"[{self.low:g}, {self.high:g}]" + (" integers" if self.kind == "int" else ""))
        if self.target == "setup":
            return f"{self.name} in {span} (read by the setup hook)"
        where = {"make": "gym.make keyword", "reset": "reset option", "attr": "attribute"}[self.target]
        return f"{self.name} in {span} ({where} {self.key})"


@dataclasses.dataclass(frozen=True, kw_only=True)
class Signal:
    """A number read off each episode: an episode statistic, an ``info`` key, an observation entry or a parameter.

    Attributes:
        source: ``return``, ``length``, ``terminated``, ``truncated``, ``info``, ``obs`` or ``param``.
        key: The ``info`` key, the observation index (as text) or the parameter name.
        at: How the steps' values make one (info and observations only, :data:`READINGS`): ``end`` (the last
            step's), ``mean``, ``min`` or ``max`` over the steps, or ``first``: the value at the first step where
            ``when`` holds.
        when: ``at = "first"``'s condition over :data:`STEP_NAMES` (``obs[6] > 0 or obs[7] > 0``).
        otherwise: ``at = "first"``'s value when ``when`` never holds: ``end``, ``mean``, ``min``, ``max`` (as
            ``at``) or a number.
    """

    source: str
    key: str = ""
    at: Literal["end", "mean", "min", "max", "first"] = "end"
    when: str = ""
    otherwise: str | float = ""

    def describe(self) -> str:
        if self.source in EPISODE_STATISTICS:
            return f"episode {self.source}"
        where = {"info": f"info[{self.key!r}]", "obs": f"observation[{self.key}]", "param": f"parameter {self.key}"}
        if self.source == "param":
            return where["param"]
        if self.at == "first":
            return f"{where[self.source]} at the first step where {self.when} (else {self.otherwise})"
        return where[self.source] + {"end": " at the end", "mean": " (mean)", "min": " (minimum)",
                                     "max": " (maximum)"}[self.at]


@dataclasses.dataclass(frozen=True, kw_only=True)
class Measure:
    """A measure of the archive: a :class:`Signal`, averaged over the episodes, with its range and cells."""

    name: str
    signal: Signal
    low: float
    high: float
    cells: int = DEFAULT_CELLS


@dataclasses.dataclass(frozen=True, kw_only=True)
class Coordinate:
    """One axis of the occupancy histogram: an observation entry (or ``info`` key), its range and its axis label."""

    signal: Signal
    low: float
    high: float
    name: str = ""

    @property
    def label(self) -> str:
        return self.name or (f"observation[{self.signal.key}]" if self.signal.source == "obs"
                             else f"info[{self.signal.key!r}]")


@dataclasses.dataclass(frozen=True, kw_only=True)
class Success:
    """An episode succeeds when ``info[info_key]`` is true at its end, or when its return is at least ``return_at_least``."""

    info_key: str = ""
    return_at_least: float | None = None

    def describe(self) -> str:
        return f"info[{self.info_key!r}] at the end" if self.info_key else f"return >= {self.return_at_least:g}"


@dataclasses.dataclass(frozen=True, kw_only=True)
class EnvSpace:
    """A whole parameter space (module docstring); built by :func:`build_space`.

    Attributes:
        env_id: The Gymnasium id, as ``gym.make`` takes it.
        env_args: Fixed ``gym.make`` keywords.
        params: The searched parameters, in solution order.
        measures: Every declared measure, by name.
        success: The success test.
        occupancy: The two coordinates of the visitation histogram, or ``()``.
        bins: Histogram bins per coordinate.
        derived: Attributes recomputed after the parameters are set (``total_mass = "masspole + masscart"``):
            arithmetic over ``env.unwrapped``'s attributes, evaluated without ``eval``.
        observation_attr: An attribute of ``env.unwrapped`` the first observation is re-read from after the
            parameters are set (CartPole's ``state``), for parameters that move the initial state.
        max_episode_steps: The episode's step limit (default: the environment's registered one).
        setup: ``python:FILE.py:FUNCTION`` or ``python:MODULE:FUNCTION``, called after each reset as
            ``FUNCTION(env, values)`` (it may return a new first observation), or ``""``. User code.
        fault: What makes an episode a failure; replaces :attr:`success` when set.
        deterministic: The space declares the environment and the agent deterministic given a level: an
            evaluation plays one episode (checked before the search by playing one level twice).
        reset_seed: The seed every episode resets with (a fixed terrain, as testers of LunarLander use), or None.
        nominal: ``{parameter name: value}`` of the nominal level the audit plays before its search (the
            ``[nominal]`` table); the parameters it leaves out are not set (the environment's own values).
        audit_measures: The default audit's measures.
        source: Where the space came from, for messages.
    """

    env_id: str
    env_args: Mapping[str, Any] = dataclasses.field(default_factory=dict)
    params: tuple[Parameter, ...] = ()
    measures: Mapping[str, Measure] = dataclasses.field(default_factory=dict)
    success: Success = Success(return_at_least=0.0)
    occupancy: tuple[Coordinate, ...] = ()
    bins: tuple[int, int] = (DEFAULT_BINS, DEFAULT_BINS)
    derived: Mapping[str, str] = dataclasses.field(default_factory=dict)
    observation_attr: str = ""
    max_episode_steps: int | None = None
    setup: str = ""
    fault: Fault | None = None
    deterministic: bool = False
    reset_seed: int | None = None
    nominal: Mapping[str, Any] = dataclasses.field(default_factory=dict)
    audit_measures: tuple[str, ...] = ()
    source: str = "command line"

    @property
    def dim(self) -> int:
        return len(self.params)

    @property
    def occupancy_shape(self) -> tuple[int, int]:
        """The histogram's shape, ``(1, 1)`` without coordinates (then it holds the share of the step limit used)."""
        return tuple(self.bins) if self.occupancy else (1, 1)

    def nominal_level(self) -> tuple["EnvSpace", dict[str, Any]]:
        """The space and values that play the nominal level: only the ``[nominal]`` parameters, set to their values,
        and no setup hook (it sets a level), so without a ``[nominal]`` table the environment as registered with
        the fixed ``gym.make`` keywords."""
        params = tuple(p for p in self.params if p.name in self.nominal)
        return dataclasses.replace(self, params=params, setup=""), dict(self.nominal)

    def values(self, solution: np.ndarray) -> dict[str, Any]:
        """``{parameter name: value}`` of a solution (a point of ``[-1, 1]^P``, clipped)."""
        solution = np.asarray(solution, dtype=np.float64).ravel()
        if solution.shape != (self.dim,):
            raise ValueError(f"a solution of this space has {self.dim} values, got {solution.shape[0]}")
        return {p.name: p.value(u) for p, u in zip(self.params, solution)}

    def solution(self, values: Mapping[str, Any]) -> np.ndarray:
        """The solution of ``{parameter name: value}`` (the inverse of :meth:`values`).

        Raises:
            SpaceError: A parameter missing or unknown, or a value out of its range.
        """
        names = [p.name for p in self.params]
        unknown, missing = sorted(set(values) - set(names)), [n for n in names if n not in values]
        if unknown or missing:
            raise SpaceError(f"level values {'lack ' + ', '.join(missing) if missing else ''}"
                             f"{'; ' if unknown and missing else ''}{'name unknown ' + ', '.join(unknown) if unknown else ''}"
                             f" (the space's parameters: {', '.join(names)})")
        return np.array([p.unit(values[p.name]) for p in self.params], dtype=np.float32)

    def measure(self, name: str) -> Measure:
        if name not in self.measures:
            raise SpaceError(f"unknown measure {name!r} (this space's: {', '.join(self.measures)})"
                             + did_you_mean(name, list(self.measures)))
        return self.measures[name]

    def to_dict(self) -> dict[str, Any]:
        """The space as a space file's TOML tables (:func:`build_space` reads it back): level files embed it."""
        def signal(s: Signal) -> dict[str, Any]:
            if s.source in EPISODE_STATISTICS:
                return {"stat": s.source}
            entry = {s.source: int(s.key) if s.source == "obs" else s.key}
            if s.source != "param":
                entry["at"] = s.at
            if s.at == "first":
                entry.update(when=s.when, otherwise=s.otherwise)
            return entry

        params = {}
        for p in self.params:
            entry: dict[str, Any] = ({"choices": list(p.choices)} if p.kind == "choice"
                                     else {"range": [int(p.low), int(p.high)] if p.kind == "int" else [p.low, p.high]})
            if p.kind == "int":
                entry["int"] = True
            if p.target == "setup":
                entry["setup"] = True
            elif p.target != "make" or p.key != p.name:
                entry[p.target] = p.key
            params[p.name] = entry
        space: dict[str, Any] = {
            "env": {"id": self.env_id, "args": dict(self.env_args), "derived": dict(self.derived),
                    **({"observation_attr": self.observation_attr} if self.observation_attr else {}),
                    **({"max_episode_steps": self.max_episode_steps} if self.max_episode_steps else {}),
                    **({"setup": self.setup} if self.setup else {}),
                    **({"deterministic": True} if self.deterministic else {}),
                    **({"reset_seed": self.reset_seed} if self.reset_seed is not None else {})},
            "params": params,
            "measures": {m.name: {**signal(m.signal), "range": [m.low, m.high], "cells": m.cells}
                         for m in self.measures.values()},
            "success": ({"info": self.success.info_key} if self.success.info_key
                        else {"return_at_least": self.success.return_at_least}),
            "audit": {"measures": list(self.audit_measures)},
        }
        if self.fault is not None:
            space["fault"] = self.fault.to_dict()
        if self.nominal:
            space["nominal"] = dict(self.nominal)
        if self.occupancy:
            space["occupancy"] = {axis: {**signal(c.signal), "range": [c.low, c.high], **({"label": c.name} if c.name else {})}
                                  for axis, c in zip("xy", self.occupancy)}
            space["occupancy"]["bins"] = list(self.bins)
        return space
