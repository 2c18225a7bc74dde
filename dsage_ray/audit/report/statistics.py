"""The numbers a collection's page computes and shows: which of an entry's numbers are the domain's, the one
failure number per level, the per-region statistics and their printed ranges, and the check that every number
the page computes with is one (a collection may come from someone else).

Nothing here knows a domain: which of an entry's numbers are shown, under which label and in which format is the
domain's registration's (:class:`~dsage_ray.domains.AuditSpec` ``columns``); a collection of a domain that is not
installed shows every numeric key of its entries.
"""

from __future__ import annotations

from decimal import ROUND_CEILING, ROUND_FLOOR, Decimal
from typing import Any, Sequence

import numpy as np

from dsage_ray.audit.collection_file import audit_declaration
from dsage_ray.audit.report.blocks import is_number
from dsage_ray.domains import ReportField

#: Regions per measure in the per-region statistics.
REGIONS_PER_MEASURE = 4
#: Entry keys every domain has; other numeric top-level keys are the domain's own numbers.
GENERIC_KEYS = {"id", "objective", "success_rate", "seed", "episodes", "search_objective", "regression"}


def region_statistics(levels: Sequence[dict[str, Any]], measures: Sequence[str], *, means: Sequence[str] = (),
                      bins: int = REGIONS_PER_MEASURE) -> list[dict[str, Any]]:
    """Levels grouped by measure region (equal-width bins over the observed range of each measure).

    A region is half-open, ``[low, high)`` per measure (the last one closed), so a level on an edge belongs to
    the upper region only.

    Returns:
        One record per non-empty region: ``ranges`` per measure (the region's edges), ``extent`` per measure
        (its levels' lowest and highest value), ``levels``, mean ``objective``, mean and min ``success_rate``,
        the mean of each of the entry keys ``means`` that every level has (Maze: ``mean_path_length``) and the
        ``worst`` level id; worst regions first.
    """
    if not levels:
        return []
    values = np.array([[lv["measures"][m] for m in measures] for lv in levels], dtype=float)
    edges = [np.linspace(values[:, j].min(), values[:, j].max(), bins + 1) for j in range(len(measures))]
    # side="right": a value on an edge opens the upper region; the clip closes the last region at the maximum.
    keys = np.stack([np.clip(np.searchsorted(e, values[:, j], side="right") - 1, 0, bins - 1)
                     for j, e in enumerate(edges)], axis=1)
    means = [key for key in means if all(key in lv for lv in levels)]
    regions = []
    for key in sorted({tuple(k) for k in keys.tolist()}):
        members = [lv for lv, k in zip(levels, keys.tolist()) if tuple(k) == key]
        worst = max(members, key=lambda lv: (lv["objective"], -lv["success_rate"]))
        region = {
            "ranges": {m: (float(edges[j][key[j]]), float(edges[j][key[j] + 1])) for j, m in enumerate(measures)},
            "extent": {m: (min(float(lv["measures"][m]) for lv in members),
                           max(float(lv["measures"][m]) for lv in members)) for m in measures},
            "levels": len(members),
            "objective": float(np.mean([lv["objective"] for lv in members])),
            "success_rate": float(np.mean([lv["success_rate"] for lv in members])),
            "min_success_rate": float(min(lv["success_rate"] for lv in members)),
            "worst": worst["id"],
        }
        region.update({key: float(np.mean([lv[key] for lv in members])) for key in means})
        regions.append(region)
    regions.sort(key=lambda r: -r["objective"])
    return regions


def report_columns(collection: dict[str, Any]) -> list[ReportField]:
    """The domain's own numbers of the entries the report shows: its registration's ``columns`` that every entry
    has as a number, measures excluded; for a domain that declares none (or is not installed), every such key."""
    numbers = _domain_numbers(collection)
    audit = audit_declaration(collection["domain"])
    if audit is not None and audit.columns:
        return [column for column in audit.columns if column.key in numbers]
    return [ReportField(key=key) for key in numbers]


def _domain_numbers(collection: dict[str, Any]) -> list[str]:
    """The domain's own scalar numbers of the entries (mean path length, completion, ...), measures excluded."""
    levels = collection["levels"]
    if not levels:
        return []
    return [key for key, value in levels[0].items()
            if key not in GENERIC_KEYS and key not in collection["measures"]
            and isinstance(value, (int, float)) and not isinstance(value, bool)
            and all(isinstance(lv.get(key), (int, float)) for lv in levels)]


def reference_numbers(collection: dict[str, Any]) -> list[str]:
    """Numeric keys of the entries' ``reference`` records (success rate first), the shared seed excluded."""
    levels = collection["levels"]
    if not collection.get("reference") or not levels or not isinstance(levels[0].get("reference"), dict):
        return []
    keys = [k for k, v in levels[0]["reference"].items()
            if k != "seed" and isinstance(v, (int, float)) and not isinstance(v, bool)]
    return sorted(keys, key=lambda k: k != "success_rate")


# ----------------------------------------------------------------------------- the failure numbers
# One failure number per level: its failure rate (1 - success rate). The objective is shown beside it only
# where it is another number (Mario's incompletion, Maze's regret); a regression audit shows the regression
# (the reference's success rate minus the agent's) instead of its [0, 1] score.

FAILURE_RATE = "failure rate"


def is_regression(c: dict[str, Any]) -> bool:
    """Whether the collection is a regression audit's: a reference agent, and levels with their regression."""
    return bool(c.get("reference")) and any("regression" in lv for lv in c["levels"])


def objective_label(c: dict[str, Any]) -> str:
    """The objective's name as the page writes it."""
    return str(c["objective"]).replace("_", " ")


def shows_objective(c: dict[str, Any]) -> bool:
    """Whether the objective needs its own column: not the failure rate itself, nor a regression's score."""
    if is_regression(c):
        return False
    return not all(abs(lv["objective"] - (1 - lv["success_rate"])) < 1e-9 for lv in c["levels"])


def failure_rate(record: dict[str, Any]) -> float:
    """A level's (or its reference record's) failure rate: 1 − its success rate."""
    return 1.0 - record["success_rate"]


def ranking_name(c: dict[str, Any]) -> str:
    """The number the levels are ranked by, worst first, as the page names it."""
    return "regression" if is_regression(c) else objective_label(c) if shows_objective(c) else FAILURE_RATE


def printed_range(low: float, high: float, values: Sequence[float], decimals: int) -> tuple[str, str]:
    """A region's range along one measure as the region table prints it and its button fills it in.

    ``low`` and ``high`` are the lowest and highest value of the region's levels. The printed ends are rounded
    outward at ``decimals`` (more where needed) so that the range, both ends included, holds exactly the levels
    between ``low`` and ``high`` among ``values``: no other level's value falls in what the rounding added.
    """
    for places in range(decimals, 16):
        step = Decimal(1).scaleb(-places)
        lo = Decimal(repr(float(low))).quantize(step, rounding=ROUND_FLOOR)
        hi = Decimal(repr(float(high))).quantize(step, rounding=ROUND_CEILING)
        if not any(float(lo) <= v < low or high < v <= float(hi) for v in values):
            return str(lo), str(hi)
    return repr(float(low)), repr(float(high))


def check_numbers(c: dict[str, Any]) -> None:
    """Checks that every number the page computes with is one (a collection may come from someone else).

    Raises:
        ValueError: A field that is not what the page needs, named (``level 3: success_rate ...``).
    """
    def number(value: Any, where: str) -> None:
        if not is_number(value):
            raise ValueError(f"collection.json: {where} is {value!r}, not a number")

    if not isinstance(c.get("measures"), list) or not all(isinstance(m, str) for m in c["measures"]):
        raise ValueError("collection.json: measures is not a list of names")
    for key in ("measure_ranges", "archive_dims", "levels"):
        if not isinstance(c.get(key), list):
            raise ValueError(f"collection.json: {key} is not a list")
    for j, pair in enumerate(c["measure_ranges"]):
        for k, value in enumerate(pair if isinstance(pair, list) and len(pair) == 2 else [pair]):
            number(value, f"measure_ranges[{j}][{k}]")
    for j, value in enumerate(c["archive_dims"]):
        if not isinstance(value, int) or isinstance(value, bool) or value < 1:
            raise ValueError(f"collection.json: archive_dims[{j}] is {value!r}, not a cell count")
    for i, lv in enumerate(c["levels"]):
        if not isinstance(lv, dict) or not isinstance(lv.get("id"), int) or isinstance(lv["id"], bool):
            raise ValueError(f"collection.json: level {i} has no integer id")
        where = f"level {lv['id']}"
        for key in ("objective", "success_rate"):
            number(lv.get(key), f"{where}: {key}")
        if not isinstance(lv.get("measures"), dict):
            raise ValueError(f"collection.json: {where}: measures is not a mapping")
        for m in c["measures"]:
            number(lv["measures"].get(m), f"{where}: measure {m!r}")
        if c.get("reference") and "regression" in lv:
            number(lv["regression"], f"{where}: regression")
            number((lv.get("reference") or {}).get("success_rate"), f"{where}: reference success_rate")
        for key in ("level_file", "image_file", "reproduce"):
            if not isinstance(lv.get(key), str):
                raise ValueError(f"collection.json: {where}: {key} is not text")
