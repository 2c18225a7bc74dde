"""Which agent kinds exist, read without importing any of them: the one table of agent kinds.

A kind is the ``KIND`` of an agent spec ``KIND:TARGET``; it maps to a factory ``factory(target, options, *,
observation_space, action_space, env=None) -> Agent``. Kinds come from dsage_ray's own table
(:data:`BUILTIN_KINDS`: the generic kinds, over any Gymnasium spaces), from the ``dsage_ray.agents``
entry-point group of installed packages, and from :func:`register_agent_kind` (this process only). A domain may
add kinds of its own for its spaces (its registration's ``agents.loaders``: the Maze's ``builtin`` and ``dcd``),
which :func:`dsage_ray.agents.loader.load_agent` takes from the domain that calls it.

This module is the base layer's half of the agent plug-ins: the domain registry lists the kinds a
domain plays from here (``dsage_ray.domains.registry``, below every domain and agent), and
:mod:`dsage_ray.agents.loader` imports the factory a spec names.
"""

from __future__ import annotations

from importlib import metadata
from typing import Any, Callable, Union

from dsage_ray import plugins

#: Entry-point group of agent kinds: the entry point's name is the kind, its value the factory.
ENTRY_POINT_GROUP = "dsage_ray.agents"
#: dsage_ray's own kinds (:mod:`dsage_ray.agents.kinds`). They are this table, not entry points: an entry point
#: dsage_ray's own installed metadata still declares (an install older than this table) is left out.
BUILTIN_KINDS: dict[str, str] = {
    "python": "dsage_ray.agents.kinds:load_python",
    "qtable": "dsage_ray.agents.kinds:load_qtable",
    "random": "dsage_ray.agents.kinds:load_random",
    "rllib": "dsage_ray.agents.kinds:load_rllib",
    "sb3": "dsage_ray.agents.kinds:load_sb3",
    "torchscript": "dsage_ray.agents.kinds:load_torchscript",
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

    Kinds registered in this process with a callable show as ``"registered in this process"``. A domain's own
    kinds are not here: its registration names them.
    """
    return dict(sorted({**BUILTIN_KINDS, **plugin_kinds()}.items()))


def plugin_kinds() -> dict[str, str]:
    """The kinds installed packages and this process add (:func:`agent_kinds` less dsage_ray's own)."""
    kinds = {name: entry.value for name, entry in installed_kinds().points.items()}
    for prefix, factory in REGISTERED.items():
        kinds[prefix] = factory if isinstance(factory, str) else "registered in this process"
    return dict(sorted(kinds.items()))


def installed_kinds() -> plugins.Plugins:
    """The kinds installed packages declare (entry points, none imported), dsage_ray's own left out."""
    # Read on every call (a directory scan, milliseconds): a package installed while a process runs
    # is seen by its next load, as it is by a freshly started Ray actor.
    return plugins.collect(point for point in metadata.entry_points(group=ENTRY_POINT_GROUP)
                           if plugins.provider(point) != plugins.OWN_DISTRIBUTION)
