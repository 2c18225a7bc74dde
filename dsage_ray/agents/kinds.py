"""dsage_ray's own agent kinds over Gymnasium spaces: one factory per kind, each checking what it loads.

A factory is ``factory(target, options, *, observation_space, action_space, env=None) -> Agent``
(:data:`dsage_ray.agents.loader.AgentFactory`); :data:`dsage_ray.agent_registry.BUILTIN_KINDS` names these
(:data:`FORMS`)::

    random                                    uniform random actions
    rllib:PATH | rllib:NAME                   a new-API-stack TorchRLModule (algorithm or RLModule checkpoint)
    sb3:PATH.zip | sb3:RUN_FOLDER             a Stable-Baselines3 save, or an RL Zoo run folder played as trained
    torchscript:PATH                          forward(obs) -> logits (Discrete) or actions (Box)
    qtable:PATH.npy                           a (states, actions) table of action values, played greedily
    python:MODULE:FUNCTION | python:FILE.py:FUNCTION   a plain function (``?batch=1``: over the batch)

Options: :mod:`dsage_ray.agents.rllib`, :mod:`dsage_ray.agents.sb3` (``?algo=PPO&greedy=0|1``) and
:mod:`dsage_ray.agents.python_policy` (``?batch=1``); ``greedy=1`` takes the most likely action instead of sampling.

Observations go in and actions come out as :mod:`dsage_ray.agents.spaces` batches them. Before anything runs, the
agent's own spaces (RLlib and SB3 record theirs) must match the environment's (as the agent's training-time wrappers
leave it: :meth:`Agent.wrap_env`), and every agent is called once on two sampled observations whose actions must lie
in the action space; any problem is an :class:`AgentError` of one line naming the spec or file. torch, ray and
stable_baselines3 are imported only by the kinds that need them.
"""

from __future__ import annotations

from typing import Any

import gymnasium
from gymnasium import spaces

from dsage_ray.agents.base import Agent, AgentError
from dsage_ray.agents.loader import SpecOptions
from dsage_ray.agents.spaces import check_actions

#: Each kind's spec forms (for error messages and help texts).
FORMS: dict[str, str] = {
    "random": "random",
    "rllib": "rllib:PATH | rllib:NAME",
    "sb3": "sb3:PATH.zip | sb3:RUN_FOLDER",
    "torchscript": "torchscript:PATH",
    "qtable": "qtable:PATH.npy",
    "python": "python:MODULE:FUNCTION | python:FILE.py:FUNCTION",
}
#: Action spaces some kind can act in; rllib and torchscript act in the first two only.
ACTION_SPACES = (spaces.Discrete, spaces.Box, spaces.MultiDiscrete, spaces.MultiBinary)


def load_random(target: str, options: SpecOptions, *, observation_space: gymnasium.Space,
                action_space: gymnasium.Space, env: Any = None) -> Agent:
    """Factory of ``random`` (no target)."""
    from dsage_ray.agents.random_agent import UniformRandomAgent

    _require_action_space(action_space, options)
    agent = UniformRandomAgent(action_space=action_space)
    return checked(agent, label=f"agent spec {options.spec!r}", options=options, observation_space=observation_space,
                   action_space=action_space, env=env)


def load_rllib(target: str, options: SpecOptions, *, observation_space: gymnasium.Space,
               action_space: gymnasium.Space, env: Any = None) -> Agent:
    """Factory of ``rllib:PATH``."""
    from dsage_ray.agents import rllib

    _require_action_space(action_space, options)
    agent, label = rllib.load_rllib(target, options, observation_space=observation_space, action_space=action_space)
    return checked(agent, label=label, options=options, observation_space=observation_space,
                   action_space=action_space, env=env)


def load_sb3(target: str, options: SpecOptions, *, observation_space: gymnasium.Space,
             action_space: gymnasium.Space, env: Any = None) -> Agent:
    """Factory of ``sb3:PATH.zip`` and ``sb3:RUN_FOLDER``."""
    from dsage_ray.agents.sb3 import load_sb3_agent

    _require_action_space(action_space, options)
    agent, label = load_sb3_agent(target, options, observation_space=observation_space, action_space=action_space,
                                  env=env)
    return checked(agent, label=label, options=options, observation_space=observation_space,
                   action_space=action_space, env=env)


def load_torchscript(target: str, options: SpecOptions, *, observation_space: gymnasium.Space,
                     action_space: gymnasium.Space, env: Any = None) -> Agent:
    """Factory of ``torchscript:PATH``."""
    from dsage_ray.agents import torchscript

    _require_action_space(action_space, options)
    agent, label = torchscript.load_torchscript(target, options, action_space=action_space)
    return checked(agent, label=label, options=options, observation_space=observation_space,
                   action_space=action_space, env=env)


def load_qtable(target: str, options: SpecOptions, *, observation_space: gymnasium.Space,
                action_space: gymnasium.Space, env: Any = None) -> Agent:
    """Factory of ``qtable:PATH.npy``."""
    from dsage_ray.agents import qtable

    agent, label = qtable.load_qtable(target, options, observation_space=observation_space, action_space=action_space)
    return checked(agent, label=label, options=options, observation_space=observation_space,
                   action_space=action_space, env=env)


def load_python(target: str, options: SpecOptions, *, observation_space: gymnasium.Space,
                action_space: gymnasium.Space, env: Any = None) -> Agent:
    """Factory of ``python:MODULE:FUNCTION`` and ``python:FILE.py:FUNCTION``."""
    from dsage_ray.agents.python_policy import load_python_agent

    _require_action_space(action_space, options)
    agent, label = load_python_agent(target, options, action_space=action_space)
    return checked(agent, label=label, options=options, observation_space=observation_space,
                   action_space=action_space, env=env)


def checked(agent: Agent, *, label: str, options: SpecOptions, observation_space: gymnasium.Space,
            action_space: gymnasium.Space, env: Any = None) -> Agent:
    """``agent``, once its options are all used and it acts in ``action_space`` on sampled observations of the
    environment as the agent's wrappers leave it (``env`` given) or of ``observation_space``.

    Raises:
        AgentError: An unknown option, or actions outside the action space (or a failed call); one line.
    """
    options.check_all_used()  # an unknown option is named before anything acts
    check_actions(agent, observation_space=agent.observed_space(observation_space), action_space=action_space,
                  label=label)
    return agent


def _require_action_space(action_space: gymnasium.Space, options: SpecOptions) -> None:
    if not isinstance(action_space, ACTION_SPACES):
        raise AgentError(f"agent spec {options.spec!r}: action space {action_space} is not supported "
                         f"(Discrete, Box, MultiDiscrete or MultiBinary)")
