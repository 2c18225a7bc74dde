"""MiniGrid's encodings and the observation/action spaces every Maze agent and the Maze simulator share.

The values come from MiniGrid itself (``minigrid.core.constants`` and ``minigrid.core.actions``), so a
change there shows up here rather than in copies. The Maze passes :data:`OBSERVATION_SPACE` and
:data:`ACTION_SPACE` to :func:`dsage_ray.agents.load_agent`, as the gym domain passes its environment's.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
from minigrid.core.actions import Actions
from minigrid.core.constants import COLOR_TO_IDX, DIR_TO_VEC, OBJECT_TO_IDX, STATE_TO_IDX

__all__ = [
    "ACTION_SPACE", "Actions", "COLOR_TO_IDX", "DIR_TO_VEC", "FORWARD", "LEFT", "NUM_ACTIONS", "NUM_HEADINGS",
    "NUM_OBJECT_KINDS", "OBJECT_TO_IDX", "OBSERVATION_SPACE", "RIGHT", "STATE_TO_IDX", "VIEW_SIZE",
]

#: Every MiniGrid action (left, right, forward, pickup, drop, toggle, done); only the first three act in a maze.
NUM_ACTIONS = len(Actions)
LEFT, RIGHT, FORWARD = int(Actions.left), int(Actions.right), int(Actions.forward)
#: Object kinds an image cell's first channel can hold (unseen .. agent).
NUM_OBJECT_KINDS = len(OBJECT_TO_IDX)
#: Headings, in MiniGrid's order: right, down, left, up.
NUM_HEADINGS = len(DIR_TO_VEC)
#: Side of the egocentric view (MiniGrid's default ``agent_view_size``, what the Maze uses).
VIEW_SIZE = 5

#: One observation as a policy sees it: MiniGrid's dict without the constant ``mission`` string.
OBSERVATION_SPACE = gym.spaces.Dict({
    "direction": gym.spaces.Discrete(NUM_HEADINGS),
    "image": gym.spaces.Box(0, 255, (VIEW_SIZE, VIEW_SIZE, 3), np.uint8),
})
ACTION_SPACE = gym.spaces.Discrete(NUM_ACTIONS)
