"""Agents: batched policies behind one interface, loaded from a spec string.

``load_agent("builtin:wall_follower")``, ``load_agent("dcd:PATH?heading_quirk=1")``,
``load_agent("torchscript:PATH")``; see :mod:`dsage_ray.agents.loader` for the spec syntax and for
adding kinds (entry-point group ``dsage_ray.agents``).
"""

from dsage_ray.agents.base import Agent, AgentError, AgentState, Observation
from dsage_ray.agents.loader import agent_kinds, load_agent, register_agent_kind

__all__ = ["Agent", "AgentError", "AgentState", "Observation", "agent_kinds", "load_agent", "register_agent_kind"]
