"""A space's ``[fault]`` table: what makes an episode a failure, read off its last step (it replaces ``[success]``).

Each key is one test and an episode is a fault when all the tests it declares hold::

    [fault]                       # LunarLander's crash (Mazouni et al., AST 2024)
    last_reward_at_most = -100    # the lander's last reward is -100 when it crashes or flies off
    terminated = true             # ... and the episode ended there, not at the step limit

Other keys: ``last_reward_at_least``, ``return_at_most``, ``truncated = true|false``, ``info = "KEY"`` (the key is
true in the last step's ``info``) and ``condition = "..."``, a condition (:mod:`~dsage_ray.domains.gym.expressions`)
over the last step's ``obs``, ``reward``, ``info`` and the episode's ``episode_return``, ``length``,
``terminated`` and ``truncated``. Reading the table runs no code.
"""

from __future__ import annotations

import dataclasses
import functools
from typing import Any, Mapping

from dsage_ray.domains.gym.errors import SpaceError
from dsage_ray.domains.gym.expressions import Expression, parse_condition
from dsage_ray.errors import did_you_mean

#: The names a fault's ``condition`` may use.
FAULT_NAMES: tuple[str, ...] = ("obs", "reward", "info", "episode_return", "length", "terminated", "truncated")
_NUMBERS = ("last_reward_at_most", "last_reward_at_least", "return_at_most")
_FLAGS = ("terminated", "truncated")
FAULT_KEYS: tuple[str, ...] = (*_NUMBERS, *_FLAGS, "info", "condition")


@dataclasses.dataclass(frozen=True, kw_only=True)
class Fault:
    """The tests of a ``[fault]`` table (module docstring); ``None`` or ``""``: not tested."""

    last_reward_at_most: float | None = None
    last_reward_at_least: float | None = None
    return_at_most: float | None = None
    terminated: bool | None = None
    truncated: bool | None = None
    info_key: str = ""
    condition: str = ""

    def describe(self) -> str:
        """``last reward <= -100 and terminated``: the fault as the report and ``gym eval`` print it."""
        parts = []
        if self.last_reward_at_most is not None:
            parts.append(f"last reward <= {self.last_reward_at_most:g}")
        if self.last_reward_at_least is not None:
            parts.append(f"last reward >= {self.last_reward_at_least:g}")
        if self.return_at_most is not None:
            parts.append(f"return <= {self.return_at_most:g}")
        parts += [name if flag else f"not {name}" for name in _FLAGS
                  if (flag := getattr(self, name)) is not None]
        if self.info_key:
            parts.append(f"info[{self.info_key!r}] at the end")
        if self.condition:
            parts.append(f"({self.condition})")
        return "fault: " + " and ".join(parts)

    def happened(self, *, last_reward: float, episode_return: float, length: int, terminated: bool,
                 truncated: bool, info: Mapping[str, Any], observation: Any) -> bool:
        """Whether an episode that ended so is a fault (every declared test holds).

        Raises:
            SpaceError: The condition names an ``info`` key or observation entry that is not there.
        """
        if self.last_reward_at_most is not None and not last_reward <= self.last_reward_at_most:
            return False
        if self.last_reward_at_least is not None and not last_reward >= self.last_reward_at_least:
            return False
        if self.return_at_most is not None and not episode_return <= self.return_at_most:
            return False
        if self.terminated is not None and bool(terminated) != self.terminated:
            return False
        if self.truncated is not None and bool(truncated) != self.truncated:
            return False
        if self.info_key and not bool(info.get(self.info_key, False)):
            return False
        if self.condition:
            names = {"obs": observation, "reward": last_reward, "info": info, "episode_return": episode_return,
                     "length": length, "terminated": terminated, "truncated": truncated}
            try:
                return _condition(self.condition).holds(names)
            except (KeyError, IndexError) as exc:
                raise SpaceError(f"[fault] condition {self.condition!r}: {exc.args[0]!r} is not there (info keys: "
                                 f"{', '.join(sorted(info)) or 'none'})") from None
            except (ArithmeticError, ValueError) as exc:
                raise SpaceError(f"[fault] condition {self.condition!r}: {exc}") from None
        return True

    def to_dict(self) -> dict[str, Any]:
        """The ``[fault]`` table (:func:`parse_fault` reads it back)."""
        table: dict[str, Any] = {name: getattr(self, name) for name in (*_NUMBERS, *_FLAGS)
                                 if getattr(self, name) is not None}
        if self.info_key:
            table["info"] = self.info_key
        if self.condition:
            table["condition"] = self.condition
        return table


@functools.lru_cache(maxsize=64)
def _condition(text: str) -> Expression:
    return parse_condition(text, where="[fault] condition", names=FAULT_NAMES)


def parse_fault(entry: Any, *, where: str) -> Fault:
    """The :class:`Fault` of a ``[fault]`` table.

    Raises:
        SpaceError: Not a table, an unknown key, a value of the wrong type, no test at all (one line).
    """
    if not isinstance(entry, Mapping):
        raise SpaceError(f"{where}: expected a table such as {{last_reward_at_most = -100, terminated = true}}")
    unknown = sorted(set(entry) - set(FAULT_KEYS))
    if unknown:
        raise SpaceError(f"{where}: unknown key(s) {', '.join(unknown)} (known: {', '.join(FAULT_KEYS)})"
                         + did_you_mean(unknown[0], list(FAULT_KEYS)))
    if not entry:
        raise SpaceError(f"{where}: declare at least one test ({', '.join(FAULT_KEYS)})")
    values: dict[str, Any] = {}
    for name in _NUMBERS:
        if name in entry:
            value = entry[name]
            if isinstance(value, bool) or not isinstance(value, (int, float)) or value != value:
                raise SpaceError(f"{where}: {name} must be a number, got {value!r}")
            values[name] = float(value)
    for name in _FLAGS:
        if name in entry:
            if not isinstance(entry[name], bool):
                raise SpaceError(f"{where}: {name} must be true or false, got {entry[name]!r}")
            values[name] = entry[name]
    if "info" in entry:
        if not (isinstance(entry["info"], str) and entry["info"]):
            raise SpaceError(f"{where}: info must name a key, got {entry['info']!r}")
        values["info_key"] = entry["info"]
    if "condition" in entry:
        parse_condition(entry["condition"], where=f"{where} condition", names=FAULT_NAMES)
        values["condition"] = entry["condition"]
    return Fault(**values)
