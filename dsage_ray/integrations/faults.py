"""The fault rule's log lines: an audit that fails, for any reason, logs one warning line (``audit of <label>
skipped: <reason>``) and never stops training."""

from __future__ import annotations

import contextlib
import logging

#: The integrations' logger, the package's own name (``dsage_ray.integrations``), as the callbacks have always
#: logged under it.
log = logging.getLogger("dsage_ray.integrations")


def describe(exc: BaseException, *, limit: int = 200) -> str:
    """``"Type: first line of the message"``, shortened to one log line."""
    lines = str(exc).strip().splitlines()
    line = lines[0] if lines else ""
    line = line if len(line) <= limit else line[: limit - 3] + "..."
    return f"{type(exc).__name__}: {line}" if line else type(exc).__name__


class SeriesFailureFilter(logging.Filter):
    """Drops the series' own warning about a failed checkpoint: the auditor's line says it instead."""

    def filter(self, record: logging.LogRecord) -> bool:
        return not (record.levelno == logging.WARNING and str(record.msg).startswith("audit-series: checkpoint"))


@contextlib.contextmanager
def one_warning():
    """While an audit runs, its failure is logged once (``audit of ... skipped``), not also by the series."""
    series_log, drop = logging.getLogger("dsage_ray.audit.series"), SeriesFailureFilter()
    series_log.addFilter(drop)
    try:
        yield
    finally:
        series_log.removeFilter(drop)
