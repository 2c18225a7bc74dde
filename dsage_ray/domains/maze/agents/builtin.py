"""Agents that need no checkpoint: ``builtin:random`` and ``builtin:wall_follower``.

``builtin:random[?actions=3]`` picks uniformly among the first ``actions`` MiniGrid actions. The default 3
is {left, right, forward}, the only actions that change anything in a maze; ``actions=7`` also draws the
four no-ops (pickup, drop, toggle, done), as an untrained 7-way policy would.

``builtin:wall_follower`` keeps its right hand on a wall, reading only the three cells next to it in the
egocentric view (ahead, left, right). Those cells are always visible, with or without see-through walls,
so it behaves identically under both settings. It is deterministic and solves every maze whose goal lies
on the wall component it follows within the step limit: all simply-connected (perfect) mazes, where every
wall is connected to the border. It is meant as a reference agent for tests.
"""

from __future__ import annotations

import numpy as np

from dsage_ray.agents.base import Agent, AgentError, AgentState, Observation
from dsage_ray.agents.loader import SpecOptions
from dsage_ray.domains.maze.agents.constants import FORWARD, LEFT, NUM_ACTIONS, OBJECT_TO_IDX, RIGHT

_EMPTY, _GOAL = OBJECT_TO_IDX["empty"], OBJECT_TO_IDX["goal"]
# Egocentric view cells, indexed [x, y]: the agent sits at (2, 4) looking toward y = 0.
_AHEAD, _LEFT_OF, _RIGHT_OF = (2, 3), (1, 4), (3, 4)

# Wall-follower modes (its per-episode state).
SEEK_WALL = 0  # walk straight until something blocks the way, so the first turn puts a wall on the right
FOLLOW = 1  # right hand on the wall
TURNED_RIGHT = 2  # just turned right around a corner: must step forward before turning right again


class RandomAgent(Agent):
    """Uniform over the first ``num_actions`` actions; stateless."""

    def __init__(self, *, num_actions: int = 3) -> None:
        if not 1 <= num_actions <= NUM_ACTIONS:
            raise ValueError(f"num_actions must be in 1..{NUM_ACTIONS}, got {num_actions}")
        self.num_actions = num_actions

    def initial_state(self, batch_size: int) -> AgentState:
        return None

    def act(self, obs: Observation, state: AgentState, rng: np.random.Generator) -> tuple[np.ndarray, AgentState]:
        return rng.integers(0, self.num_actions, size=len(obs["direction"]), dtype=np.int64), state


class WallFollowerAgent(Agent):
    """Deterministic right-hand-rule agent; its state is a mode per episode, ``(n,)`` int8.

    Per step, in priority order: step onto the goal if it is ahead, turn toward it if it is beside;
    while seeking a wall, go forward until blocked; when following, turn right if the right cell is open
    (unless it just did), else go forward if open, else turn left.
    """

    def initial_state(self, batch_size: int) -> AgentState:
        return np.full(batch_size, SEEK_WALL, dtype=np.int8)

    def act(self, obs: Observation, state: AgentState, rng: np.random.Generator) -> tuple[np.ndarray, AgentState]:
        obj = np.asarray(obs["image"])[..., 0]
        ahead, left, right = (obj[:, x, y] for x, y in (_AHEAD, _LEFT_OF, _RIGHT_OF))
        open_ahead = (ahead == _EMPTY) | (ahead == _GOAL)
        open_right = (right == _EMPTY) | (right == _GOAL)
        mode = np.asarray(state)

        # Rule table, lowest priority first; later assignments override earlier ones.
        following = mode != SEEK_WALL
        actions = np.full(len(mode), LEFT, dtype=np.int64)  # blocked ahead (and right): turn left
        new_mode = np.where(following, FOLLOW, mode).astype(np.int8)
        new_mode[~following & ~open_ahead] = FOLLOW  # found a wall ahead; the left turn puts it on the right
        actions[open_ahead] = FORWARD
        turn_right = following & open_right & (mode != TURNED_RIGHT)
        actions[turn_right] = RIGHT
        new_mode[turn_right] = TURNED_RIGHT
        # The goal overrides everything: it is only ever adjacent for one decision.
        actions[left == _GOAL] = LEFT
        actions[right == _GOAL] = RIGHT
        actions[ahead == _GOAL] = FORWARD
        return actions, new_mode


def load_builtin_agent(target: str, options: SpecOptions) -> Agent:
    """Factory for ``builtin:random[?actions=N]`` and ``builtin:wall_follower``."""
    if target == "random":
        return RandomAgent(num_actions=options.get_int("actions", 3, minimum=1, maximum=NUM_ACTIONS))
    if target == "wall_follower":
        return WallFollowerAgent()
    raise AgentError(f"builtin agent {target!r}: unknown (known: random, wall_follower)")
