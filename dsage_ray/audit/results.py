"""A collection folder as Python objects: what :func:`dsage_ray.run_audit` returns.

:class:`Collection` reads ``collection.json`` (:mod:`dsage_ray.audit.collection_file`, any format
version) and gives its levels, worst first, as :class:`CollectionLevel` items with paths resolved
against the folder, plus the failure-diversity numbers of :mod:`dsage_ray.audit.summary`.
"""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path
from typing import Any, Mapping

from dsage_ray.audit.collection_file import COLLECTION_FILE, load_collection
from dsage_ray.audit.summary import failure_summary, format_summary

#: The report page inside a collection folder (:mod:`dsage_ray.audit.report`).
REPORT_FILE = "report.html"


@dataclasses.dataclass(frozen=True, kw_only=True)
class CollectionLevel:
    """One level of a collection, with the numbers of its recorded re-evaluation.

    Attributes:
        id: Its rank in the collection (0 is the worst).
        objective: The audit objective (e.g. the failure rate) of the re-evaluation.
        success_rate: Share of the ``episodes`` the agent solved.
        seed: The evaluation seed; ``reproduce`` with it prints the same numbers.
        episodes: Episodes (Mario: runs) of the re-evaluation.
        measures: The level's measures by name.
        level_path: The level file (``dsage-ray maze eval --layout`` / ``mario eval --level`` read it).
        image_path: The PNG of the level with the agent's occupancy.
        reproduce: The shell command that re-evaluates the level with ``seed``.
        regression: Regression audits: the reference's success rate minus this agent's; else None.
        fields: Every key of the level's ``collection.json`` entry, the domain's own included.
    """

    id: int
    objective: float
    success_rate: float
    seed: int
    episodes: int
    measures: Mapping[str, float]
    level_path: Path
    image_path: Path
    reproduce: str
    regression: float | None
    fields: Mapping[str, Any]


@dataclasses.dataclass(frozen=True, kw_only=True)
class Collection:
    """An audit's collection: the levels where the agent failed, each reproducible with its seed.

    Attributes:
        path: The collection folder.
        domain: The audited domain (``maze``, ``mario``, ...).
        agent: The audited agent's spec.
        reference: The reference agent's spec of a regression audit, else None.
        objective: What the search maximised (``failure_rate``, ``regret``, ``regression``, ...).
        levels: The levels, worst first.
        summary: The failure-diversity numbers (:func:`~dsage_ray.audit.summary.failure_summary`):
            ``levels``, ``with_failures``, ``never_solved``, ``failure_cells``, ``cvar10`` (and, for a
            regression audit, ``regressed`` and ``mean_regression_top10``).
        search_dir: The search's run folder (its TensorBoard events), if recorded.
        data: The whole ``collection.json``.
    """

    path: Path
    domain: str
    agent: str
    reference: str | None
    objective: str
    levels: tuple[CollectionLevel, ...]
    summary: Mapping[str, Any]
    search_dir: Path | None
    data: Mapping[str, Any]

    @property
    def report_path(self) -> Path:
        """The self-contained HTML report of the collection."""
        return self.path / REPORT_FILE

    @property
    def summary_line(self) -> str:
        """:attr:`summary` in one line, as ``dsage-ray audit`` prints it."""
        return format_summary(dict(self.summary))

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> "Collection":
        """Reads a collection folder (or its ``collection.json``) written by an audit.

        Raises:
            ValueError: ``path`` holds no readable collection.
        """
        path = Path(path)
        folder = path.parent if path.name == COLLECTION_FILE and path.is_file() else path
        data = load_collection(folder)
        levels = tuple(
            CollectionLevel(
                id=int(entry["id"]),
                objective=float(entry["objective"]),
                success_rate=float(entry["success_rate"]),
                seed=int(entry["seed"]),
                episodes=int(entry["episodes"]),
                measures={name: float(value) for name, value in entry["measures"].items()},
                level_path=folder / entry["level_file"],
                image_path=folder / entry["image_file"],
                reproduce=entry["reproduce"],
                regression=None if entry.get("regression") is None else float(entry["regression"]),
                fields=entry,
            )
            for entry in data["levels"]
        )
        return cls(path=folder, domain=data["domain"], agent=data["agent"], reference=data.get("reference"),
                   objective=data["objective"], levels=levels, summary=failure_summary(data),
                   search_dir=Path(data["search_dir"]) if data.get("search_dir") else None, data=data)
