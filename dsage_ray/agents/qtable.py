"""A tabular agent (``qtable:PATH.npy``): a ``(states, actions)`` array of action values, played greedily.

Tabular Q-learning and SARSA agents (Taxi, FrozenLake, CliffWalking) are saved as one NumPy array; the agent takes
``argmax(table[state])`` in a ``Discrete(states)`` observation space, ties to the lowest action as ``numpy.argmax``
breaks them (how such tables are evaluated, e.g. Mazouni et al.'s Taxi agent). The file is read with
``allow_pickle=False``: it is data, and loading it runs no code.
"""

from __future__ import annotations

import zipfile
from typing import Any

import gymnasium
import numpy as np
from gymnasium import spaces

from dsage_ray.agents.base import Agent, AgentError, AgentState
from dsage_ray.agents.loader import SpecOptions, describe_exception, require_file


class QTableAgent(Agent):
    """``argmax(table[observation])`` for each running episode.

    Args:
        table: ``(states, actions)`` finite action values.
    """

    def __init__(self, *, table: np.ndarray) -> None:
        self.greedy_actions = np.argmax(table, axis=1).astype(np.int64)

    def initial_state(self, batch_size: int) -> AgentState:
        return None

    def act(self, obs: Any, state: AgentState, rng: np.random.Generator) -> tuple[np.ndarray, AgentState]:
        return self.greedy_actions[np.asarray(obs, dtype=np.int64).reshape(-1)], None


def read_table(path: str, *, label: str) -> np.ndarray:
    """The 2-D finite numeric array in the ``.npy`` file ``path``.

    Raises:
        AgentError: Not such a file, or not such an array (one line).
    """
    try:
        table = np.load(path, allow_pickle=False)
    except (ValueError, OSError, EOFError, zipfile.BadZipFile) as exc:
        raise AgentError(f"{label}: not a NumPy .npy array ({describe_exception(exc)})") from None
    if isinstance(table, np.lib.npyio.NpzFile):
        names = ", ".join(table.files)
        table.close()
        raise AgentError(f"{label}: an .npz archive ({names}), not one .npy array of action values")
    if table.ndim != 2 or not np.issubdtype(table.dtype, np.number) or np.issubdtype(table.dtype, np.complexfloating):
        raise AgentError(f"{label}: expected a (states, actions) array of action values, got shape {table.shape} "
                         f"of {table.dtype}")
    if not np.isfinite(table).all():
        raise AgentError(f"{label}: {int((~np.isfinite(table)).sum())} action values are not finite")
    return table


def load_qtable(target: str, options: SpecOptions, *, observation_space: gymnasium.Space,
                action_space: gymnasium.Space) -> tuple[Agent, str]:
    """The agent ``qtable:PATH.npy`` names, and the label its errors start with.

    Raises:
        AgentError: The file, or its shape against ``Discrete`` observation and action spaces (one line).
    """
    path = require_file(target, what="Q-table file")
    label = f"Q-table file {str(path)!r}"
    table = read_table(str(path), label=label)
    if not isinstance(observation_space, spaces.Discrete) or not isinstance(action_space, spaces.Discrete):
        raise AgentError(f"{label}: a Q-table acts on Discrete observations and actions; this environment has "
                         f"{observation_space} and {action_space}")
    if observation_space.start != 0 or action_space.start != 0:
        raise AgentError(f"{label}: a Q-table's rows and columns count from 0; this environment's spaces start at "
                         f"{observation_space.start} and {action_space.start}")
    expected = (int(observation_space.n), int(action_space.n))
    if table.shape != expected:
        raise AgentError(f"{label}: its shape {table.shape} is not the environment's (states, actions) {expected}: "
                         f"it was trained on another environment (another map or state encoding)")
    return QTableAgent(table=table), label
