"""Plain Python policies (``python:MODULE:FUNCTION``, ``python:FILE.py:FUNCTION``): the user's own code, called as is.

By default the function maps one observation to one action and is called once per running episode. With
``?batch=1`` it takes the batch of the episodes still running (:func:`~dsage_ray.agents.spaces.stack_observations`)
and returns one action per row, so that wrapping another library's batched policy costs one call per step.

A function with an ``rng`` parameter gets the caller's generator (so a stochastic policy stays reproducible); any
other function must be deterministic. Importing the module runs it: a ``python:`` agent is code (docs/TRUST.md).
"""

from __future__ import annotations

import hashlib
import importlib
import importlib.util
import inspect
import sys
from typing import Any, Callable

import gymnasium
import numpy as np

from dsage_ray.agents.base import Agent, AgentError, AgentState, tree_map
from dsage_ray.agents.loader import SpecOptions, describe_exception, require_file
from dsage_ray.agents.spaces import batch_size, finish_actions


class PythonFunctionAgent(Agent):
    """A plain function as a batched agent (module docstring).

    Args:
        function: ``function(observation[, rng=rng]) -> action``, or with ``batched`` the same over a batch.
        action_space: The environment's action space.
        batched: Whether ``function`` takes the whole batch.
    """

    def __init__(self, *, function: Callable[..., Any], action_space: gymnasium.Space, batched: bool = False) -> None:
        self.function = function
        self.action_space = action_space
        self.batched = batched
        self._takes_rng = _accepts_rng(function)

    def initial_state(self, batch_size: int) -> AgentState:
        return None

    def act(self, obs: Any, state: AgentState, rng: np.random.Generator) -> tuple[np.ndarray, AgentState]:
        extra = {"rng": rng} if self._takes_rng else {}
        if self.batched:
            actions = np.asarray(self.function(obs, **extra))
            if len(actions) != batch_size(obs):
                raise AgentError(f"a ?batch=1 function gave {len(actions)} actions for {batch_size(obs)} observations")
            return finish_actions(actions, self.action_space), None
        actions = [self.function(tree_map(lambda x, i=i: x[i], obs), **extra) for i in range(batch_size(obs))]
        return finish_actions(np.asarray(actions), self.action_space), None


def _accepts_rng(function: Callable[..., Any]) -> bool:
    try:
        return "rng" in inspect.signature(function).parameters
    except (TypeError, ValueError):  # builtins without a signature
        return False


def load_python_agent(target: str, options: SpecOptions, *, action_space: gymnasium.Space) -> tuple[Agent, str]:
    """Loads ``python:TARGET[?batch=1]``; returns the agent and the label its errors carry.

    Raises:
        AgentError: A malformed target, a module or file that does not import, or no such callable.
    """
    batched = options.get_bool("batch", False)
    label = f"python policy {target!r}"
    function = import_object(target, label=label, what="function")
    return PythonFunctionAgent(function=function, action_space=action_space, batched=batched), label


def import_object(target: str, *, label: str, what: str) -> Callable[..., Any]:
    """The callable ``MODULE:NAME`` or ``FILE.py:NAME`` names, without its ``python:`` (importing it runs the module).

    Raises:
        AgentError: A malformed target, a module or file that does not import, or no such callable (one line).
    """
    location, sep, name = target.rpartition(":")
    if not sep or not location or not name:
        raise AgentError(f"{label}: expected python:MODULE:{what.upper()} or python:FILE.py:{what.upper()}")
    module = import_file(location, label=label) if location.endswith(".py") else import_module(location, label=label)
    found = getattr(module, name, None)
    if found is None:
        raise AgentError(f"{label}: {location!r} has no {what} {name!r}")
    if not callable(found):
        raise AgentError(f"{label}: {location}.{name} is a {type(found).__name__}, not callable")
    return found


def import_module(name: str, *, label: str) -> Any:
    """Imports an installed module; AgentError (one line) if it is missing or its top-level code fails."""
    try:
        return importlib.import_module(name)
    except ModuleNotFoundError as exc:
        if exc.name and (name == exc.name or name.startswith(exc.name + ".")):
            raise AgentError(f"{label}: module {name!r} not found (is it installed or on PYTHONPATH?)") from None
        raise AgentError(f"{label}: importing {name!r} failed ({describe_exception(exc)})") from None
    except Exception as exc:  # noqa: BLE001 - the module's own top-level code can raise anything
        raise AgentError(f"{label}: importing {name!r} failed ({describe_exception(exc)})") from None


def import_file(location: str, *, label: str) -> Any:
    """Imports a .py file from where it lies, without adding its folder to ``sys.path``."""
    path = require_file(location, what="python file").resolve()
    # A name of its own per file: two policies called pol.py must not replace each other in sys.modules.
    name = f"_dsage_python_{path.stem}_{hashlib.sha256(str(path).encode()).hexdigest()[:12]}"
    spec = importlib.util.spec_from_file_location(name, path)
    if spec is None or spec.loader is None:
        raise AgentError(f"{label}: {str(path)!r} cannot be imported as a Python file")
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module  # dataclasses and pickling look the module up while it runs
    try:
        spec.loader.exec_module(module)
    except Exception as exc:  # noqa: BLE001 - the file's top-level code can raise anything
        sys.modules.pop(name, None)
        raise AgentError(f"{label}: importing {str(path)!r} failed ({describe_exception(exc)})") from None
    return module
