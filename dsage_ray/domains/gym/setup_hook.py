"""A space's setup hook, ``[env] setup = "python:FILE.py:FUNCTION"`` (or ``python:MODULE:FUNCTION``): user code.

The simulator calls ``FUNCTION(env, values)`` after each reset, once the level's attributes and derived attributes
are set, with the (wrapped) environment and ``{parameter name: value}``. It reaches what no ``make``, ``reset`` or
``attr`` target does (LunarLander's initial force is applied inside ``reset``). It returns the episode's first
observation if it changed it, else ``None``.

Importing the hook runs its file, with the user's permissions: a space naming one is code, not data
(docs/TRUST.md). Reading a space imports nothing; the hook is imported the first time a level is played.
"""

from __future__ import annotations

from typing import Any, Callable

from dsage_ray.agents.base import AgentError
from dsage_ray.agents.loader import describe_exception
from dsage_ray.agents.python_policy import import_object
from dsage_ray.domains.gym.errors import SpaceError

_LOADED: dict[str, Callable[..., Any]] = {}


def user_code_notices(space: Any) -> list[str]:
    """The lines an audit or ``gym eval`` prints before it plays a space that runs user code: its setup hook, and an
    environment id naming a module (``MODULE:ENV``: ``gym.make`` imports the module first)."""
    notices = []
    if ":" in space.env_id:
        module = space.env_id.split(":", 1)[0]
        notices.append(f"note: this space runs user code: its environment id {space.env_id!r} imports the module "
                       f"{module!r} (docs/TRUST.md)")
    if space.setup:
        notices.append(f"note: this space runs user code: its setup hook {space.setup!r} is imported and called "
                       f"after every reset (docs/TRUST.md)")
    return notices


def load_setup(spec: str) -> Callable[..., Any]:
    """The function a setup spec names, imported once per process (the ``python:`` agent kind's importer).

    Raises:
        SpaceError: No such file, module or function, or its import failed (one line).
    """
    if spec not in _LOADED:
        try:
            _LOADED[spec] = import_object(spec.removeprefix("python:"), label=f"[env] setup {spec!r}",
                                          what="function")
        except AgentError as exc:
            raise SpaceError(str(exc)) from None
    return _LOADED[spec]


def call_setup(spec: str, env: Any, values: dict[str, Any]) -> Any:
    """Calls the hook; what it returned (the new first observation, or None).

    Raises:
        SpaceError: The hook raised (its error in one line).
    """
    function = load_setup(spec)
    try:
        return function(env, values)
    except SpaceError:
        raise
    except Exception as exc:  # noqa: BLE001 - user code can raise anything; one line names it
        raise SpaceError(f"[env] setup {spec!r} failed: {describe_exception(exc)}") from None
