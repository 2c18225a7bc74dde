"""The package's exceptions: one base, one kind per exit code of the ``dsage-ray`` command.

Every error the package raises on purpose is a :class:`DsageError`. Its kind says whose problem
it is, and :func:`describe` turns any exception the CLI reports into ``(exit code, one line)``:

* ``1`` :class:`DsageError` — a failure the run reports that fits no kind below;
* ``2`` :class:`InputError` — a bad flag, config key or value, config file, agent spec, layout,
  level, checkpoint or generator file (argparse's own usage errors exit 2 too);
* ``3`` :class:`ResourceError` — the machine or cluster cannot run the request: ``--workers 64``
  on two cores, Java or the ``mario-gpt`` data missing;
* ``4`` :class:`TrialFailed` — a Ray Tune trial failed for good: its error and its ``error.txt``;
* ``5`` :class:`Interrupted` — trials stopped before their budget (continue them with ``--resume``);
* ``130`` — Ctrl+C.

The kinds also derive from the built-in exception their users already catch (an
:class:`InputError` is a ``ValueError``, the others ``RuntimeError``s), so the older names
(``ConfigError``, ``AgentError``, ``PoolResourceError``, ...) keep working as before.
"""

from __future__ import annotations

import difflib
from pathlib import Path
from typing import Any, ClassVar

#: Exit code of a command stopped with Ctrl+C (128 + SIGINT, as shells report it).
INTERRUPTED_BY_USER = 130


class DsageError(Exception):
    """Base of every error dsage_ray raises on purpose; ``exit_code`` is the CLI's exit status."""

    exit_code: ClassVar[int] = 1


class InputError(DsageError, ValueError):
    """Input the user can fix: a flag, a config, a file; the message names it."""

    exit_code = 2


class ResourceError(DsageError, RuntimeError):
    """The machine or the Ray cluster cannot run what was asked (CPUs, Java, data files)."""

    exit_code = 3


class TrialFailed(DsageError, RuntimeError):
    """A Tune trial failed more often than its ``max_failures``.

    Args:
        message: The trial's error, in one line.
        error_file: The trial's ``error.txt`` (Tune writes the whole traceback there), if known.
    """

    exit_code = 4

    def __init__(self, message: str, *, error_file: str | Path | None = None) -> None:
        self.error_file = Path(error_file) if error_file else None
        super().__init__(f"{message} (log: {self.error_file})" if self.error_file else message)


class Interrupted(DsageError, RuntimeError):
    """Work stopped before it was done and can be continued."""

    exit_code = 5


def describe(exc: BaseException) -> tuple[int, str]:
    """The exit code and the one-line message the CLI prints for ``exc``.

    :class:`DsageError` carries its own code; the built-in families the CLI also reports map to
    the same table: ``ValueError`` and ``OSError`` (a missing or unwritable file) are input
    errors, another ``RuntimeError`` is a plain failure, ``KeyboardInterrupt`` is Ctrl+C.
    """
    if isinstance(exc, KeyboardInterrupt):
        return INTERRUPTED_BY_USER, "interrupted"
    if isinstance(exc, DsageError):
        code = exc.exit_code
    elif isinstance(exc, (ValueError, OSError)):
        code = InputError.exit_code
    else:
        code = DsageError.exit_code
    if isinstance(exc, OSError) and exc.strerror and not isinstance(exc, DsageError):
        message = f"{exc.filename}: {exc.strerror}" if exc.filename else exc.strerror
    else:
        message = str(exc) or type(exc).__name__
    return code, " ".join(message.split())


def did_you_mean(name: Any, known: Any) -> str:
    """``"; did you mean 'X'?"`` for the closest of ``known`` to ``name``, or ``""``: the hint every
    "unknown ..." message ends with."""
    close = difflib.get_close_matches(str(name), [str(k) for k in known], n=1, cutoff=0.6)
    return f"; did you mean {close[0]!r}?" if close else ""
