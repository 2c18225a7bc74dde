"""The nominal check before an audit's search: the agent plays its domain's nominal level first.

An agent played other than as it was trained (its observation normalisation not applied, frame stacking
missing, another environment version) fails everywhere, and an audit of it would report those failures as
the agent's. So before a search the agent plays the domain's nominal level (:class:`~dsage_ray.types.NominalDomain`:
gym the environment as registered or the space's ``[nominal]`` values, Maze an open room, Mario a flat level)
for a few episodes, and the audit stops in one line where it does far worse there than expected:

* with an expected return ``E`` (``--expect-return``, else the agent's own training record,
  :attr:`~dsage_ray.agents.base.Agent.expected_return`): the nominal mean return ``m`` of ``n`` episodes with
  sample standard deviation ``s`` is far worse when ``m < E − max(0.25·|E|, 3·s·√(2/n))``. The second term
  is three standard errors of ``E − m`` when ``E`` is itself a mean of about ``n`` episodes (the RL Zoo
  evaluates 5 to 10), so episode noise alone does not stop an audit; it stands in for an absolute floor, which
  would have the units of each environment's return (MiniGrid's is at most 1, LunarLander's in the hundreds).
  Measured on the RL Zoo's ``evaluations.npz`` (docs/GUIDE.md, ``benchmarks/nominal_rule.py``): 0.25·|E| alone
  stops the zoo's own DQN LunarLander agent in 10% of 10-episode checks (its episodes spread 32 to 225), the rule
  in 0.6%; every random agent is stopped.
* without one: where no episode succeeds.

A domain without a nominal level is not checked. The check is recorded in the audit folder
(:data:`NOMINAL_FILE`), so ``--resume`` and ``--collect-only`` reuse it without playing again, and the
collection and its report carry it.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path
from typing import Any, Callable, Literal, Mapping

import numpy as np

from dsage_ray.errors import InputError
from dsage_ray.types import NominalResult

#: The record of the check in an audit folder.
NOMINAL_FILE = "nominal.json"
#: Far worse: below the expected return by more than this share of its size ...
RELATIVE_MARGIN = 0.25
#: ... and by more than this many standard errors of the difference (the floor that episode noise sets).
NOISE_MARGIN = 3.0
#: Keeps the nominal episodes' seed apart from the runner's and the collection's.
_SEED_TAG = 0x90A1
#: What a verdict means, for the printed line.
Verdict = Literal["ok", "far_worse", "never_succeeds"]


class NominalCheckFailed(InputError):
    """The agent does far worse on the nominal level than expected (or never succeeds there): the audit would
    report artefacts of how it is played. The message names the likely cause and ``--allow-failing-nominal``."""


@dataclasses.dataclass(frozen=True, kw_only=True)
class NominalCheck:
    """The nominal check of one audit.

    Attributes:
        result: What the agent did on the nominal level.
        expected: The return it was expected to reach there, or None where no figure is known.
        expected_source: Where :attr:`expected` came from (``--expect-return``, ``evaluations.npz``).
        threshold: The return below which the agent counts as far worse (None without :attr:`expected`).
        verdict: ``ok``, ``far_worse`` or ``never_succeeds`` (the latter only without an expected figure).
        allowed: The audit went on despite a failing verdict (``--allow-failing-nominal``).
    """

    result: NominalResult
    expected: float | None
    expected_source: str
    threshold: float | None
    verdict: Verdict
    allowed: bool = False

    @property
    def passed(self) -> bool:
        return self.verdict == "ok"

    def line(self) -> str:
        """The one line the audit prints before its search."""
        return "nominal check: " + self.summary(hint=True)

    def summary(self, *, hint: bool = False) -> str:
        """The check in words: the level, the return and success, the expected figure and the verdict; ``hint``
        says how to give an expected figure where none was known."""
        r = self.result
        spread = f" ± {r.return_std:.3g} s.d." if r.episodes > 1 else ""
        text = (f"{r.level}, {r.episodes} episode{'s' if r.episodes != 1 else ''}: "
                f"{r.return_name} {_number(r.mean_return)}{spread}, success {r.success_rate:.2f}")
        if self.expected is not None:
            text += (f"; expected {_number(self.expected)} ({self.expected_source}), far worse below "
                     f"{_number(self.threshold)}")
        elif hint:
            text += "; no expected return known (--expect-return X gives one)"
        if self.passed:
            return text + ": ok"
        return text + f": {self.problem()}" + (" (went on: --allow-failing-nominal)" if self.allowed else "")

    def problem(self) -> str:
        """What failed and its likely causes, in words."""
        r = self.result
        if self.verdict == "far_worse":
            what = f"FAR WORSE than expected ({_number(r.mean_return)} < {_number(self.threshold)})"
        else:
            what = "it NEVER SUCCEEDS there"
        return f"{what}; likely {r.causes or 'the agent is not played as it was trained'}"

    def stop_message(self) -> str:
        """The one-line error that stops the audit."""
        r = self.result
        numbers = f"{r.return_name} {_number(r.mean_return)}, success {r.success_rate:.2f} in {r.episodes} episodes"
        if self.expected is not None:
            numbers += f", expected {_number(self.expected)} ({self.expected_source})"
        return (f"nominal check failed on {r.level} ({numbers}): {self.problem()}; nothing was searched. Pass "
                f"--allow-failing-nominal (allow_failing_nominal=True) to audit it anyway")

    def to_dict(self) -> dict[str, Any]:
        """The record an audit folder and a collection keep (plain JSON)."""
        return {"result": dataclasses.asdict(self.result), "expected": self.expected,
                "expected_source": self.expected_source, "threshold": self.threshold, "verdict": self.verdict,
                "allowed": self.allowed, "summary": self.summary()}

    @classmethod
    def from_dict(cls, record: Any, *, where: str) -> "NominalCheck":
        """A record :meth:`to_dict` wrote, checked field by field (a folder may come from someone else).

        Raises:
            InputError: Not such a record (``where`` names the file).
        """
        try:
            fields = {f.name: f for f in dataclasses.fields(NominalResult)}
            raw = dict(record["result"])
            if set(raw) - set(fields):
                raise ValueError(f"unknown fields {sorted(set(raw) - set(fields))}")
            result = NominalResult(**{key: _typed(raw[key], fields[key].type, key) for key in raw})
            verdict = record["verdict"]
            if verdict not in ("ok", "far_worse", "never_succeeds"):
                raise ValueError(f"verdict {verdict!r}")
            return cls(result=result, expected=_typed(record["expected"], "float | None", "expected"),
                       expected_source=_typed(record["expected_source"], "str", "expected_source"),
                       threshold=_typed(record["threshold"], "float | None", "threshold"), verdict=verdict,
                       allowed=_typed(record["allowed"], "bool", "allowed"))
        except (KeyError, TypeError, ValueError) as exc:
            raise InputError(f"{where}: not a nominal check record ({exc})") from None


def _typed(value: Any, kind: str, key: str) -> Any:
    """``value`` checked to be of the dataclass field type ``kind`` (as the annotation's text)."""
    if value is None and kind.endswith("| None"):
        return None
    base = kind.split("|")[0].strip()
    ok = {"str": isinstance(value, str), "bool": isinstance(value, bool),
          "int": isinstance(value, int) and not isinstance(value, bool),
          "float": isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)}[base]
    if not ok:
        raise ValueError(f"{key} is {value!r}, not {base}")
    return float(value) if base == "float" else value


def _number(value: float | None) -> str:
    return "?" if value is None else f"{value:.4g}" if abs(value) < 1000 else f"{value:,.0f}"


def far_worse_threshold(expected: float, *, return_std: float, episodes: int) -> float:
    """The nominal mean return below which an agent expected to reach ``expected`` does far worse (module docstring)."""
    noise = NOISE_MARGIN * return_std * math.sqrt(2.0 / max(episodes, 1))
    return expected - max(RELATIVE_MARGIN * abs(expected), noise)


def judge(result: NominalResult, *, expect_return: float | None = None) -> NominalCheck:
    """The verdict on ``result``: against ``expect_return`` where given, else the agent's own expected return,
    else whether any episode succeeded."""
    if expect_return is not None:
        expected, source = float(expect_return), "--expect-return"
    elif result.expected_return is not None:
        expected, source = float(result.expected_return), result.expected_return_source or "the agent's record"
    else:
        expected, source = None, ""
    if expected is None:
        return NominalCheck(result=result, expected=None, expected_source="", threshold=None,
                            verdict="ok" if result.success_rate > 0 else "never_succeeds")
    threshold = far_worse_threshold(expected, return_std=result.return_std, episodes=result.episodes)
    return NominalCheck(result=result, expected=expected, expected_source=source, threshold=threshold,
                        verdict="ok" if result.mean_return >= threshold else "far_worse")


def nominal_seed(run_seed: int) -> int:
    """The seed of an audit's nominal episodes, from its run seed."""
    return int(np.random.SeedSequence([int(run_seed), _SEED_TAG]).generate_state(1)[0])


def play_nominal(domain: Any, *, run_seed: int, expect_return: float | None = None) -> NominalCheck | None:
    """Plays ``domain``'s agent on its nominal level and judges it; None for a domain without a nominal level.

    Raises:
        InputError: The domain could not play it (one line).
    """
    from dsage_ray.types import NominalDomain

    if not isinstance(domain, NominalDomain):
        return None
    try:
        result = domain.play_nominal(seed=nominal_seed(run_seed))
    except InputError:
        raise
    except (ValueError, OSError) as exc:
        raise InputError(f"nominal check: {exc}") from exc
    return judge(result, expect_return=expect_return)


def check_expect_return(value: float | None) -> None:
    """Refuses an ``expect_return`` that is not a finite number."""
    if value is not None and (isinstance(value, bool) or not isinstance(value, (int, float))
                              or not math.isfinite(value)):
        raise InputError(f"expect_return must be a finite number, got {value!r}")


def read_record(folder: str | Path) -> NominalCheck | None:
    """The check an audit folder recorded, or None where it holds none.

    Raises:
        InputError: A record that does not read.
    """
    import json

    path = Path(folder) / NOMINAL_FILE
    if not path.is_file():
        return None
    try:
        record = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise InputError(f"{path}: not a nominal check record ({type(exc).__name__})") from None
    return NominalCheck.from_dict(record, where=str(path))


def write_record(folder: str | Path, check: NominalCheck) -> Path:
    """Writes the record of ``check`` into ``folder`` (atomically); its path."""
    from dsage_ray.io import atomic_write_json

    path = Path(folder) / NOMINAL_FILE
    atomic_write_json(path, check.to_dict())
    return path


def audit_nominal(play: Callable[[], NominalCheck | None], *, folder: Path, reuse: bool,
                  allow_failing: bool = False, echo: Callable[[str], None] = print) -> NominalCheck | None:
    """The nominal check of an audit: the one its folder recorded (``reuse``: a resumed audit, a collect-only one),
    else ``play()``'s, printed in one line and recorded in ``folder``.

    A recorded check is not played again and does not stop the audit: the audit went past it when it began.

    Raises:
        NominalCheckFailed: A check played now failed, and ``allow_failing`` is not set (nothing is written).
    """
    recorded = read_record(folder) if reuse else None
    if recorded is not None:
        echo(f"{recorded.line()} (recorded in {folder / NOMINAL_FILE}, not played again)")
        return recorded
    check = play()
    if check is None:
        return None
    if not check.passed:
        if not allow_failing:
            raise NominalCheckFailed(check.stop_message())
        check = dataclasses.replace(check, allowed=True)
    echo(check.line())
    write_record(folder, check)
    return check


def record_summary(record: Mapping[str, Any]) -> str:
    """The report's one-line text of a collection's ``nominal`` record (any malformed field shown as ``?``)."""
    try:
        return NominalCheck.from_dict(record, where="collection.json").summary()
    except InputError:
        return "? (the collection's nominal record does not read)"
