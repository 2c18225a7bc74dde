"""``python:...?batch=1``: the function takes the batch of running episodes, one call per step."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

from dsage_ray.agents.base import AgentError
from dsage_ray.agents import load_agent

OBS = gym.spaces.Box(-10.0, 10.0, (4,), np.float32)
ACT = gym.spaces.Discrete(2)
SOURCE = """
import numpy as np
CALLS = []

def batched(obs):
    CALLS.append(len(obs))
    return (obs[:, 2] > 0).astype(int)

def short(obs):
    return [0]
"""


@pytest.fixture
def policy_file(tmp_path):
    path = tmp_path / "batched_policy.py"
    path.write_text(SOURCE)
    return path


def test_a_batched_function_is_called_once_per_step_with_every_running_episode(policy_file):
    agent = load_agent(f"python:{policy_file}:batched?batch=1", observation_space=OBS, action_space=ACT)
    calls = agent.function.__globals__["CALLS"]
    calls.clear()
    obs = np.random.default_rng(0).uniform(-1, 1, (7, 4)).astype(np.float32)
    actions, _ = agent.act(obs, agent.initial_state(7), np.random.default_rng(0))
    assert calls == [7] and actions.tolist() == (obs[:, 2] > 0).astype(int).tolist()


def test_a_batched_function_giving_too_few_actions_is_named(policy_file):
    with pytest.raises(AgentError, match="a \\?batch=1 function gave 1 actions for 2 observations"):
        load_agent(f"python:{policy_file}:short?batch=1", observation_space=OBS, action_space=ACT)
