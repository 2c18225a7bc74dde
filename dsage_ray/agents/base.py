"""The one policy interface every agent implements.

Evaluations run many episodes at once, so the interface is batched: observations for ``n``
active episodes and their recurrent state go in, ``n`` actions come out. Episodes that finish
leave the batch (:meth:`Agent.select_state`), which keeps later steps cheap.
"""

from __future__ import annotations

import abc
from typing import Any, Callable

import numpy as np

from dsage_ray.errors import InputError

#: A batch of ``n`` observations (:func:`dsage_ray.agents.spaces.stack_observations`): for a Dict space, such as the
#: Maze's ``image`` ``(n, 5, 5, 3)`` uint8 and ``direction`` ``(n,)`` int64, a dict of arrays.
Observation = dict[str, np.ndarray]
#: Whatever an agent carries between steps (LSTM ``(h, c)``, nothing, ...); opaque to callers.
AgentState = Any


class AgentError(InputError):
    """An agent spec or checkpoint that cannot be loaded; the message says why."""


class Agent(abc.ABC):
    """A batched, possibly recurrent, possibly stochastic policy."""

    #: Human-readable identity (the spec it was loaded from).
    spec: str = ""
    #: The mean return its own training record gives on the nominal environment (an RL Zoo folder's last
    #: ``evaluations.npz`` row), or None where the agent brings none; the nominal check compares against it.
    expected_return: float | None = None
    #: Where :attr:`expected_return` was read from, for the nominal check's line (``"evaluations.npz"``).
    expected_return_source: str = ""

    @abc.abstractmethod
    def initial_state(self, batch_size: int) -> AgentState:
        """State for ``batch_size`` fresh episodes."""

    @abc.abstractmethod
    def act(self, obs: Observation, state: AgentState, rng: np.random.Generator) -> tuple[np.ndarray, AgentState]:
        """Actions ``(n,)`` int64 for the ``n`` episodes in ``obs``, and the next state.

        All randomness must come from ``rng`` so that an evaluation is reproducible from its seed.
        """

    def reduced_precision(self) -> "Agent | None":
        """A faster, lower-precision copy of this policy for estimates (``experimental.screen_precision``), whose
        actions may differ from this agent's now and then; None (the default): the agent has none."""
        return None

    def wrap_env(self, env: Any) -> Any:
        """The environment as the agent was trained in it: ``env`` inside the agent's training-time wrappers (an RL
        Zoo folder's ``env_wrapper``); the default is ``env`` itself. Simulators call it on every environment they
        build for this agent."""
        return env

    def observed_space(self, env_space: Any) -> Any:
        """The observation space this agent acts on, given the environment's: the wrapped environment's where
        :meth:`wrap_env` wraps it (as recorded when the agent was loaded: some wrappers change the environment they
        wrap, so an environment is wrapped once, never twice); the default is ``env_space`` itself."""
        return env_space

    def select_state(self, state: AgentState, index: np.ndarray) -> AgentState:
        """Keeps only the episodes at ``index`` (the ones still running)."""
        return tree_map(lambda x: x[index], state)


def tree_map(fn: Callable[[Any], Any], tree: Any) -> Any:
    """``fn`` applied to every leaf of nested tuples, lists and dicts (None stays None)."""
    if tree is None:
        return None
    if isinstance(tree, (tuple, list)):
        return type(tree)(tree_map(fn, t) for t in tree)
    if isinstance(tree, dict):
        return {k: tree_map(fn, v) for k, v in tree.items()}
    return fn(tree)

