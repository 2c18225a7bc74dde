"""Agents: batched policies behind one interface, loaded from a spec string for the spaces they act in.

``load_agent("rllib:ppo_cartpole", observation_space=env.observation_space, action_space=env.action_space)``;
see :mod:`dsage_ray.agents.loader` for the spec syntax and for adding kinds (entry-point group
``dsage_ray.agents``), and :mod:`dsage_ray.agents.kinds` for dsage_ray's own. The Maze's agents (the wall
follower, DCD/ACCEL, its MiniGrid conventions) are the Maze's: :func:`dsage_ray.domains.maze.agents.load_maze_agent`.
"""

from dsage_ray.agents.base import Agent, AgentError, AgentState, Observation
from dsage_ray.agents.loader import agent_kinds, load_agent, register_agent_kind

__all__ = ["Agent", "AgentError", "AgentState", "Observation", "agent_kinds", "load_agent", "register_agent_kind"]
