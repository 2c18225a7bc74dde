"""The Maze's agents: the kinds it registers (``builtin:``, ``dcd:``, and its ``rllib:`` and ``torchscript:``
conventions on MiniGrid's observation) and the one call that loads any agent the Maze plays.

The kinds are named in the Maze's registration (:data:`dsage_ray.domains.maze.plugin.DOMAIN`, ``agents.loaders``);
:func:`load_maze_agent` passes them, with MiniGrid's spaces, to :func:`dsage_ray.agents.load_agent`, so plug-in
kinds of the ``dsage_ray.agents`` entry-point group load for the Maze too.
"""

from __future__ import annotations

from dsage_ray.agents.base import Agent
from dsage_ray.agents.loader import load_agent
from dsage_ray.domains.maze.agents.constants import ACTION_SPACE, OBSERVATION_SPACE
from dsage_ray.domains.maze.plugin import DOMAIN

__all__ = ["load_maze_agent"]


def load_maze_agent(spec: str) -> Agent:
    """The agent ``spec`` names, for the Maze: its own kinds first, then the agent layer's and the plug-ins'.

    Raises:
        AgentError: An unknown kind or option, or a target that cannot be loaded; one line.
    """
    return load_agent(spec, observation_space=OBSERVATION_SPACE, action_space=ACTION_SPACE,
                      kinds=DOMAIN.agents.loaders)
