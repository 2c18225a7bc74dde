"""Reading a space's step signals (observation entries and ``info`` keys) over the episodes played side by side.

A signal is read after every step of every episode; :class:`StepReadings` keeps, per episode, what its ``at``
needs (the last value, the sum, the minimum and maximum, and for ``at = "first"`` the value at the first step
where its ``when`` holds) and :meth:`StepReadings.values` makes one number per episode of them.
"""

from __future__ import annotations

import functools
from typing import Any, Mapping, Sequence

import numpy as np

from dsage_ray.domains.gym.errors import SpaceError
from dsage_ray.domains.gym.expressions import Expression, parse_condition
from dsage_ray.domains.gym.space_model import STEP_NAMES, Signal


def signal_key(signal: Signal) -> str:
    """A signal's key in recorded values (``info:x:end``; ``obs:0:first:obs[6] > 0:end``)."""
    event = f":{signal.when}:{signal.otherwise}" if signal.at == "first" else ""
    return f"{signal.source}:{signal.key}:{signal.at}{event}"


def read_signal(signal: Signal, observation: Any, info: Mapping[str, Any]) -> float:
    """One step's value of an ``info`` or ``obs`` signal.

    Raises:
        KeyError, IndexError: The ``info`` key or observation entry is missing (:class:`StepReadings` names it).
    """
    if signal.source == "info":
        return float(np.asarray(info[signal.key], dtype=np.float64).ravel()[0])
    return float(np.asarray(observation, dtype=np.float64).ravel()[int(signal.key)])


@functools.lru_cache(maxsize=64)
def step_condition(text: str) -> Expression:
    """A measure's ``when``, parsed once per process."""
    return parse_condition(text, where="when", names=STEP_NAMES)


class StepReadings:
    """What the step signals of ``episodes`` episodes have read so far.

    Args:
        signals: The signals to read (those of other sources are left out).
        episodes: Episodes played side by side.
        env_id: For messages.
    """

    def __init__(self, signals: Sequence[Signal], *, episodes: int, env_id: str) -> None:
        self.signals = tuple(dict.fromkeys(s for s in signals if s.source in ("info", "obs")))
        self.env_id = env_id
        keys = [signal_key(s) for s in self.signals]
        self.last = {k: np.zeros(episodes) for k in keys}
        self.sums = {k: np.zeros(episodes) for k in keys}
        self.mins = {k: np.full(episodes, np.inf) for k in keys}
        self.maxs = {k: np.full(episodes, -np.inf) for k in keys}
        self.first = {k: np.full(episodes, np.nan) for k in keys}
        self.fired = {k: np.zeros(episodes, bool) for k in keys}

    def record(self, i: int, *, step: int, observation: Any, reward: float, info: Mapping[str, Any]) -> None:
        """Reads every signal after step ``step`` (1 at the first) of episode ``i``.

        Raises:
            SpaceError: An ``info`` key or observation entry that is not there, or a ``when`` that cannot be read.
        """
        holds: dict[str, bool] = {}  # a condition shared by several signals is evaluated once per step
        for signal in self.signals:
            key = signal_key(signal)
            try:
                value = read_signal(signal, observation, info)
            except (KeyError, IndexError):
                raise SpaceError(f"environment {self.env_id!r}: {signal.describe()} is not there "
                                 f"(info keys: {', '.join(sorted(info)) or 'none'}; observation size "
                                 f"{np.asarray(observation).size})") from None
            self.last[key][i] = value
            self.sums[key][i] += value
            self.mins[key][i] = min(self.mins[key][i], value)
            self.maxs[key][i] = max(self.maxs[key][i], value)
            if signal.at != "first" or self.fired[key][i]:
                continue
            if signal.when not in holds:
                holds[signal.when] = self._holds(signal.when, step=step, observation=observation, reward=reward,
                                                 info=info)
            if holds[signal.when]:
                self.first[key][i], self.fired[key][i] = value, True

    def _holds(self, when: str, *, step: int, observation: Any, reward: float, info: Mapping[str, Any]) -> bool:
        try:
            return step_condition(when).holds({"obs": observation, "reward": reward, "info": info, "step": step})
        except (KeyError, IndexError) as exc:
            raise SpaceError(f"environment {self.env_id!r}: when = {when!r} reads {exc.args[0]!r}, which is not "
                             f"there (info keys: {', '.join(sorted(info)) or 'none'}; observation size "
                             f"{np.asarray(observation).size})") from None
        except (ArithmeticError, ValueError) as exc:
            raise SpaceError(f"environment {self.env_id!r}: when = {when!r} cannot be computed ({exc})") from None

    def values(self, signal: Signal, lengths: np.ndarray) -> np.ndarray:
        """The signal's value per episode, once the episodes are over."""
        key = signal_key(signal)
        by_reading = {"end": lambda: self.last[key], "mean": lambda: self.sums[key] / np.maximum(lengths, 1),
                      "min": lambda: self._at_least_one(self.mins[key], lengths),
                      "max": lambda: self._at_least_one(self.maxs[key], lengths)}
        if signal.at != "first":
            return by_reading[signal.at]()
        otherwise = (np.full(len(lengths), float(signal.otherwise)) if isinstance(signal.otherwise, float)
                     else by_reading[signal.otherwise]())
        return np.where(self.fired[key], self.first[key], otherwise)

    @staticmethod
    def _at_least_one(values: np.ndarray, lengths: np.ndarray) -> np.ndarray:
        # An episode of no step has read nothing: 0, as its "end" and "mean" are.
        return np.where(lengths > 0, values, 0.0)
