"""The collection file: where it lives in a collection folder, its format, and reading it.

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


def load_collection(path: str | Path) -> dict[str, Any]:
    """Reads a collection folder's ``collection.json`` (or the file itself); ValueError when it is not one."""
    path = Path(path)
    file = path / COLLECTION_FILE if path.is_dir() else path
    try:
        collection = json.loads(file.read_text())
    except (OSError, json.JSONDecodeError) as exc:
        raise ValueError(f"{file}: not a readable collection ({exc})") from None
    if not isinstance(collection, dict) or collection.get("format") != FORMAT:
        raise ValueError(f"{file}: not a dsage_ray collection (expected format {FORMAT})")
    return collection


def audit_declaration(domain: str):
    """The audit declaration of ``domain``; None for a domain that is not installed (or declares no audit)."""
    try:
        return get_domain(domain).audit
    except InputError:
        return None
