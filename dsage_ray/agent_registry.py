"""Which agent kinds exist, read without importing any of them.

A kind is the ``KIND`` of an agent spec ``KIND:TARGET``; it maps to a factory ``factory(target, options) ->
Agent``. Kinds come from dsage_ray's own table (:data:`BUILTIN_KINDS`), from the ``dsage_ray.agents``
entry-point group of installed packages, and from :func:`register_agent_kind` (this process only).

This module is the base layer's half of the agent plug-ins: the domain registry lists the kinds a
domain plays from here (``dsage_ray.domains.registry``, below every domain and agent), and
:mod:`dsage_ray.agents.loader` imports the factory a spec names.
"""

from __future__ import annotations

from typing import Any, Callable, Union

from dsage_ray import plugins

#: Entry-point group of agent kinds: the entry point's name is the kind, its value the factory.
ENTRY_POINT_GROUP = "dsage_ray.agents"
#: dsage_ray's own kinds, exactly as ``pyproject.toml`` declares them; read only when the installed
#: metadata lacks them (a source checkout on ``PYTHONPATH``, or an install older than the entry points).
BUILTIN_KINDS: dict[str, str] = {
    "builtin": "dsage_ray.agents.builtin:load_builtin_agent",
    "dcd": "dsage_ray.agents.dcd:load_dcd_agent",
    "rllib": "dsage_ray.agents.rllib:load_rllib_agent",
    "torchscript": "dsage_ray.agents.torchscript:load_torchscript_agent",
}
#: Kinds added by :func:`register_agent_kind`, in this process only; they take precedence. A value is a
#: ``"module:function"`` path or the factory itself.
REGISTERED: dict[str, Union[str, Callable[..., Any]]] = {}


def register_agent_kind(prefix: str, factory: Union[str, Callable[..., Any]]) -> None:
    """Makes ``PREFIX:TARGET`` specs load through ``factory`` (a callable or a ``"module:function"`` path).

    The kind exists in the calling process only: Ray's simulator actors do not see it. A kind they
    must load is an entry point of the ``dsage_ray.agents`` group of an installed package.

    Raises:
        ValueError: ``prefix`` is not a Python identifier.
    """
    if not prefix.isidentifier():
        raise ValueError(f"agent kind prefix must be an identifier, got {prefix!r}")
    REGISTERED[prefix] = factory


def agent_kinds() -> dict[str, str]:
    """Every known kind and where its factory lives (``"module:function"``), importing none of them.

    Kinds registered in this process with a callable show as ``"registered in this process"``.
    """
    kinds = dict(BUILTIN_KINDS)
    for name, entry in installed_kinds().points.items():
        kinds[name] = entry.value
    for prefix, factory in REGISTERED.items():
        kinds[prefix] = factory if isinstance(factory, str) else "registered in this process"
    return dict(sorted(kinds.items()))


def installed_kinds() -> plugins.Plugins:
    """The kinds installed packages declare (entry points, none imported)."""
    # Read on every call (a directory scan, milliseconds): a package installed while a process runs
    # is seen by its next load, as it is by a freshly started Ray actor.
    return plugins.scan(ENTRY_POINT_GROUP)
