"""Domains: a search space, an agent simulator and the measures of the agent's behaviour."""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from dsage_ray.config import RunConfig
    from dsage_ray.types import Domain


#: The domains a config may name.
DOMAINS = ("maze", "mario")


def domain_class(name: str) -> type:
    """The domain class called ``name``; imported lazily so Maze users never need Java."""
    if name == "maze":
        from dsage_ray.domains.maze.domain import MazeDomain

        return MazeDomain
    if name == "mario":
        from dsage_ray.domains.mario.domain import MarioDomain

        return MarioDomain
    raise ValueError(f"domain: unknown domain {name!r} (known: {', '.join(DOMAINS)})")


def build_domain(config: "RunConfig") -> "Domain":
    """Builds the domain a run config names."""
    return domain_class(config.domain)(config=config.domain_config)
