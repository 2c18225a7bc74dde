"""The Maze's ``rllib:`` kind: an RLModule on MiniGrid's observation, acting in MiniGrid's first ``k`` actions.

The policy is :class:`~dsage_ray.agents.rllib.RLlibAgent`, loaded as every ``rllib:`` agent is
(:mod:`dsage_ray.agents.rllib`, options ``policy`` and ``greedy``); what is the Maze's own is the check: the
observation (the module's, or its pipeline's input) must be :data:`~dsage_ray.domains.maze.agents.constants.
OBSERVATION_SPACE` and the action space ``Discrete(k)``, ``k <= 7``, MiniGrid's first ``k`` actions (a policy may
have learnt only left, right and forward). No sampled-observation call: a random image is no MiniGrid encoding.
"""

from __future__ import annotations

from typing import Any

from dsage_ray.agents.base import AgentError
from dsage_ray.agents.loader import SpecOptions
from dsage_ray.agents.rllib import RLlibAgent, load_rllib_policy
from dsage_ray.domains.maze.agents.constants import NUM_ACTIONS, OBSERVATION_SPACE


def check_spaces(module: Any, *, source: str, observation_space: Any = None) -> None:
    """AgentError unless the module observes the Maze's dict observation and acts in ``Discrete(k <= 7)``.

    ``observation_space``: what the agent takes, where that is not the module's own space (a pipeline's input).
    """
    import gymnasium as gym

    space = module.observation_space if observation_space is None else observation_space
    expected = OBSERVATION_SPACE
    ok = (isinstance(space, gym.spaces.Dict) and set(space.spaces) == set(expected.spaces)
          and isinstance(space["image"], gym.spaces.Box) and space["image"].shape == expected["image"].shape
          and isinstance(space["direction"], gym.spaces.Discrete) and space["direction"].n == expected["direction"].n)
    if not ok:
        raise AgentError(f"rllib checkpoint {source!r}: observation space {space} does not match the maze observation "
                         f"{expected}")
    actions = module.action_space
    if not (isinstance(actions, gym.spaces.Discrete) and 1 <= actions.n <= NUM_ACTIONS):
        raise AgentError(f"rllib checkpoint {source!r}: action space {actions} is not Discrete(k), k <= {NUM_ACTIONS}")


def load_rllib_agent(target: str, options: SpecOptions) -> RLlibAgent:
    """Factory of the Maze's ``rllib:PATH[?policy=NAME&greedy=0|1]``."""
    policy = options.get_str("policy", "default_policy")
    greedy = options.get_bool("greedy", False)
    module, pipelines = load_rllib_policy(target, policy=policy, check=check_spaces)
    return RLlibAgent(module=module, greedy=greedy, pipelines=pipelines)
