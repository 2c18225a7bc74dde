"""The agent kinds a help text lists: one formatter for every command that takes an agent spec.

``audit``, ``compare``, ``audit-series``, ``surrogate pretrain`` and the domains' ``eval`` commands all
list the kinds from here, so no command offers other kinds than another for the same domain.
"""

from __future__ import annotations

from dsage_ray.agents.loader import RUNS_CODE_NOTE
from dsage_ray.domains import agent_forms, get_domain


def agent_kinds_help(domain: str | None = None) -> str:
    """The agent spec forms from the domain registrations, then the note that some kinds run code:
    ``gym: rllib:PATH, ...; mario: astar[:ITERATIONS]; maze: builtin:NAME, ... loading ... (docs/TRUST.md)``.

    Args:
        domain: Only this domain's forms, without its name (``dsage-ray maze eval``): its registration alone is
            read. None: every domain's (:func:`~dsage_ray.domains.agent_forms`), each after its name, for the
            commands that take ``--domain``.
    """
    if domain is not None:
        agents = get_domain(domain).agents
        listed = ", ".join(agents.kinds().values() if agents else ())
    else:
        listed = "; ".join(f"{name}: {', '.join(forms)}" for name, forms in agent_forms().items())
    return f"{listed}. {RUNS_CODE_NOTE}"


def checkpoint_kinds() -> list[str]:
    """The agent kinds that name a file or folder (``rllib``, ``sb3``, ...): what ``audit-series --kind`` takes."""
    return sorted({form.split(":")[0] for forms in agent_forms().values() for form in forms
                   if form.split(":", 1)[-1].startswith("PATH")})
