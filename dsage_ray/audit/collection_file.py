"""The collection file: where it lives in a collection folder, its formats, and reading it.

Kept apart from :mod:`dsage_ray.audit.collection` (which builds collections and renders their
report) so the report can read a collection without importing the module that writes one.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from dsage_ray.config import RunConfig
from dsage_ray.domains import build_domain

COLLECTION_FILE = "collection.json"
FORMAT = "dsage_ray.collection.v2"
#: Maze-only collections written before Mario audits and regression audits; :func:`load_collection` upgrades them.
FORMAT_V1 = "dsage_ray.collection.v1"


def load_collection(path: str | Path) -> dict[str, Any]:
    """Reads a collection folder's ``collection.json`` (or the file itself); ValueError when it is not one.

    A v1 collection (Maze only, before regression audits) comes back with the v2 keys filled in —
    ``domain`` ``"maze"``, ``reference`` None, each level's ``level_file`` (its ``layout_file``) and
    ``reproduce`` — and its ``format`` unchanged, so readers need only know v2.
    """
    path = Path(path)
    file = path / COLLECTION_FILE if path.is_dir() else path
    try:
        collection = json.loads(file.read_text())
    except (OSError, json.JSONDecodeError) as exc:
        raise ValueError(f"{file}: not a readable collection ({exc})") from None
    if not isinstance(collection, dict) or collection.get("format") not in (FORMAT, FORMAT_V1):
        raise ValueError(f"{file}: not a dsage_ray collection (expected format {FORMAT} or {FORMAT_V1})")
    if collection["format"] == FORMAT_V1:
        _upgrade_v1(collection, folder=file.parent)
    return collection


def _upgrade_v1(collection: dict[str, Any], *, folder: Path) -> None:
    # v1 predates other domains: its collections are Maze's by definition.
    collection.setdefault("domain", "maze")
    collection.setdefault("reference", None)
    # The agent's evaluation as v1 recorded it, for its reproduce commands.
    domain = build_domain(RunConfig.build({
        "domain": "maze", "maze.agent": collection["agent"], "maze.episodes": collection["episodes"],
        "maze.see_through_walls": collection.get("see_through_walls", True)}))
    for level in collection["levels"]:
        level.setdefault("level_file", level["layout_file"])
        level.setdefault("reproduce", domain.reproduce_command(folder.resolve() / level["layout_file"],
                                                               seed=level["seed"]))
