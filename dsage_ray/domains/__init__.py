"""Domains: a search space, an agent simulator and the measures of the agent's behaviour.

Every domain, Maze and Mario included, is a plug-in found through :mod:`.registry` (the
``dsage_ray.domains`` entry-point group); nothing here imports a domain until one is built.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Protocol

from dsage_ray.domains.registry import (DEFAULT_DOMAIN, ENTRY_POINT_GROUP, AgentKinds, AuditFlag, AuditSpec,
                                        CheckedSection, CompletingSection, DomainSpec, ReportField, agent_forms,
                                        domain_names, get_domain, register_domain, unregister_domain)

if TYPE_CHECKING:
    from dsage_ray.types import Domain

__all__ = ["DEFAULT_DOMAIN", "ENTRY_POINT_GROUP", "AgentKinds", "AuditFlag", "AuditSpec", "CheckedSection",
           "CompletingSection", "DomainSpec", "ReportField", "agent_forms", "build_domain", "domain_class",
           "domain_names", "get_domain", "register_domain", "unregister_domain"]


def domain_class(name: str) -> type:
    """The domain class registered as ``name`` (imported now, not before).

    Raises:
        InputError: No such domain; the message lists the registered ones.
    """
    return get_domain(name).domain_class()


class NamesADomain(Protocol):
    """What :func:`build_domain` reads of a run config (:class:`dsage_ray.config.RunConfig`).

    A protocol, not the class: the config imports this package (to check a domain's name), so naming it here,
    even for types only, would make the two a loop.
    """

    @property
    def domain(self) -> str:
        """The domain's registered name."""

    @property
    def domain_config(self) -> Any:
        """The domain's own config section."""


def build_domain(config: NamesADomain) -> "Domain":
    """Builds the domain a run config names from its section."""
    return domain_class(config.domain)(config=config.domain_config)
