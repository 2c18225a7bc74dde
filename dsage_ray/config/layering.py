"""The layers a config is built from, below its explicit keys: the domain's presets (the scale) and variants
(the search), each a set of dotted keys, never a code branch."""

from __future__ import annotations

from typing import Any

from dsage_ray.domains.registry import get_domain

#: The DSAGE variants of every domain (its registration adds its QD baselines, e.g. ``map_elites``).
#: Paper variants as data: each is a set of keys, never a code branch.
COMMON_VARIANTS: dict[str, dict[str, Any]] = {
    "dsage": {"surrogate.kind": "two_stage", "selection.method": "downsample"},
    "dsage_only_anc": {"surrogate.kind": "two_stage", "selection.method": "full"},
    # A one-stage model predicts no occupancy, so every measure has its own head.
    "dsage_only_down": {"surrogate.kind": "one_stage", "selection.method": "downsample",
                        "surrogate.occupancy_sum_measure": ""},
    "dsage_basic": {"surrogate.kind": "one_stage", "selection.method": "full", "surrogate.occupancy_sum_measure": ""},
    "dsage_rsample": {"surrogate.kind": "two_stage", "selection.method": "random"},
    # Domain randomisation: the random emitter draws every level from the domain's own generator.
    "dr": {"surrogate.kind": "none", "qd.emitter": "random", "qd.num_emitters": 5, "qd.batch_size": 30,
           "selection.screen_episodes": 0, "selection.screen_gain": False},
}


def presets(domain: str) -> dict[str, dict[str, Any]]:
    """The presets of a registered domain (``paper``, ``tiny``, ...), each a dict of dotted keys."""
    return {name: dict(keys) for name, keys in get_domain(domain).presets.items()}


def variants(domain: str) -> dict[str, dict[str, Any]]:
    """The variants of a registered domain: :data:`COMMON_VARIANTS` plus the domain's own."""
    return {**COMMON_VARIANTS, **{name: dict(keys) for name, keys in get_domain(domain).variants.items()}}


def paper_comparison(domain: str) -> tuple[str, ...]:
    """The variants ``dsage-ray ablate`` compares by default (the paper's Table 2 rows for Maze and Mario)."""
    return tuple(get_domain(domain).comparison)
