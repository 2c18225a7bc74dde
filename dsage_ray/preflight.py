"""Checks before a search starts: the agents load, the simulator runs on this machine.

A run whose agent cannot be loaded would otherwise fail every evaluation in the simulators and end in
an error about something else (an empty surrogate dataset, a Tune traceback). Every entry point that
starts a search (:func:`dsage_ray.run`, :func:`dsage_ray.ablate`, :func:`dsage_ray.run_audit`) calls
:func:`preflight` first, so such input fails in one line before Ray or the run starts.
"""

from __future__ import annotations

import json

from dsage_ray.config import RunConfig
from dsage_ray.domains import build_domain
from dsage_ray.errors import DsageError, InputError, describe
from dsage_ray.types import PreflightDomain


def preflight(*configs: RunConfig) -> list[object]:
    """Builds the domain of each distinct domain section among ``configs`` and runs its ``preflight()``.

    Returns:
        The domain of each config, in order (configs with the same domain section share one), so that a caller that
        plays one next (the audit's nominal check) need not build it, and load its agent, again.

    Domains without a ``preflight`` method (it is optional, :class:`~dsage_ray.types.AuditableDomain`)
    are only built.

    A ``surrogate.init`` warm start is loaded and checked against its config too (so it must still be
    there when a run resumes).

    Raises:
        InputError: An agent that does not load (a missing file, a wrong checkpoint format), or a
            ``surrogate.init`` that does not fit its config; the message names it.
        ResourceError: A missing simulator (Java or the Mario AI jar).
    """
    from dsage_ray.core.warm_start import check_warm_start

    domains: dict[tuple[str, str], object] = {}
    built: list[object] = []
    warm_starts_checked: set[tuple] = set()
    for config in configs:
        values = config.to_dict()
        key = (config.domain, json.dumps(values.get(config.domain), sort_keys=True))
        fresh = key not in domains
        if fresh:
            domains[key] = build_domain(config)
        domain = domains[key]
        built.append(domain)
        # A grid shares its warm start: read and check it once per domain section and surrogate section.
        warm_key = (*key, json.dumps(values["surrogate"], sort_keys=True))
        if config.surrogate.init and warm_key not in warm_starts_checked:
            warm_starts_checked.add(warm_key)
            check_warm_start(config, domain=domain)
        if not fresh:
            continue
        if not isinstance(domain, PreflightDomain):
            continue
        try:
            domain.preflight()
        except DsageError:
            raise
        except (ValueError, OSError) as exc:  # a plug-in's preflight may raise the built-in kinds
            raise InputError(describe(exc)[1]) from exc
    return built
