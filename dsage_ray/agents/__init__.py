"""Agents: batched policies behind one interface, loaded from a spec string.

``load_agent("builtin:wall_follower")``, ``load_agent("dcd:PATH?heading_quirk=1")``,
``load_agent("torchscript:PATH")``; see :mod:`dsage_ray.agents.loader` for the spec syntax.
"""

from dsage_ray.agents.base import Agent, AgentError, AgentState, Observation
from dsage_ray.agents.loader import load_agent, register_agent_kind

__all__ = ["Agent", "AgentError", "AgentState", "Observation", "load_agent", "register_agent_kind"]
