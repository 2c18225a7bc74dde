"""Installed plug-ins: the entry points of one group, by name, with the names two packages claim.

Domains (``dsage_ray.domains``) and agent kinds (``dsage_ray.agents``) are both found this way; each
caller decides when to read again and how to word its errors.
"""

from __future__ import annotations

import dataclasses
from importlib import metadata
from typing import Iterable

#: The distribution whose own entry points are listed first.
OWN_DISTRIBUTION = "dsage_ray"


@dataclasses.dataclass(frozen=True)
class Plugins:
    """The entry points of one group.

    Attributes:
        points: The entry point of each name (dsage_ray's own first, then in metadata order).
        clashes: Names that two or more installed packages map to different values: every such entry
            point, in the same order. A name in ``clashes`` is also in ``points`` (its first one); using it
            is the caller's error to raise.
    """

    points: dict[str, metadata.EntryPoint]
    clashes: dict[str, tuple[metadata.EntryPoint, ...]]


def scan(group: str) -> Plugins:
    """Reads the installed entry points of ``group`` (a directory scan; imports none of them)."""
    return collect(metadata.entry_points(group=group))


def collect(entry_points: Iterable[metadata.EntryPoint]) -> Plugins:
    """Groups entry points by name (:class:`Plugins`); the same value declared twice is one entry point."""
    ordered = sorted(entry_points, key=lambda p: provider(p) != OWN_DISTRIBUTION)
    by_name: dict[str, dict[str, metadata.EntryPoint]] = {}
    for point in ordered:
        by_name.setdefault(point.name, {}).setdefault(point.value, point)
    return Plugins(points={name: next(iter(values.values())) for name, values in by_name.items()},
                   clashes={name: tuple(values.values()) for name, values in by_name.items() if len(values) > 1})


def provider(point: metadata.EntryPoint) -> str | None:
    """The name of the distribution that declares ``point`` (None when the metadata does not say)."""
    dist = getattr(point, "dist", None)
    return None if dist is None else dist.name


def describe(point: metadata.EntryPoint) -> str:
    """``"mod:attr (package NAME)"`` for error messages."""
    name = provider(point)
    return f"{point.value} (package {name})" if name else f"{point.value} (an installed package)"
