"""The collection file: where it lives in a collection folder, its formats, and reading it.

Kept apart from :mod:`dsage_ray.audit.collection` (which builds collections and renders their
report) so the report can read a collection without importing the module that writes one.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from dsage_ray.domains import get_domain
from dsage_ray.errors import InputError

COLLECTION_FILE = "collection.json"
FORMAT = "dsage_ray.collection.v2"
#: Maze-only collections written before Mario audits and regression audits; :func:`load_collection` upgrades them.
FORMAT_V1 = "dsage_ray.collection.v1"


def load_collection(path: str | Path) -> dict[str, Any]:
    """Reads a collection folder's ``collection.json`` (or the file itself); ValueError when it is not one.

    What an older collection lacks its domain fills in (the ``upgrade`` of its registration's audit), with
    its ``format`` unchanged, so readers need only know the current one: a v1 collection (Maze only, before
    regression audits) comes back with the v2 keys — ``domain`` ``"maze"``, ``reference`` None, each level's
    ``level_file`` (its ``layout_file``) and ``reproduce``. A collection of a domain that is not installed
    is read as it is.
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
        collection.setdefault("domain", "maze")  # v1 predates other domains
    audit = audit_declaration(collection["domain"])
    if audit is not None:
        audit.upgrade_collection(collection, folder=file.parent)
    return collection


def audit_declaration(domain: str):
    """The audit declaration of ``domain``; None for a domain that is not installed (or declares no audit)."""
    try:
        return get_domain(domain).audit
    except InputError:
        return None
