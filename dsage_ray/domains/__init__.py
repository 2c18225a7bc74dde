"""Domains: a search space, an agent simulator and the measures of the agent's behaviour."""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from dsage_ray.config import RunConfig
    from dsage_ray.types import Domain


def build_domain(config: "RunConfig") -> "Domain":
    """Builds the domain a run config names; imported lazily so Maze users never need Java."""
    if config.domain == "maze":
        from dsage_ray.domains.maze.domain import MazeDomain

        return MazeDomain(config=config.maze)
    if config.domain == "mario":
        from dsage_ray.domains.mario.domain import MarioDomain

        return MarioDomain(config=config.mario)
    raise ValueError(f"domain: unknown domain {config.domain!r}")
