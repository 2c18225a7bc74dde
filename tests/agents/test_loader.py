"""Spec parsing and the kind table (dsage_ray/agents/loader.py): a bad spec fails with one clear line.

The kinds' own files are tested beside their modules: the Maze's (``builtin``, ``dcd``, its ``torchscript``
convention) in tests/domains/maze/agents/, the generic ones in tests/agents/test_kinds.py and friends.
"""

from __future__ import annotations

import numpy as np
import pytest

from dsage_ray import agent_registry
from dsage_ray.agents import Agent, register_agent_kind
from dsage_ray.domains.maze.agents import load_maze_agent
from tests.domains.maze.agents.conftest import load_error


@pytest.mark.parametrize(
    "spec, needle",
    [
        ("nonsense:foo", "unknown kind 'nonsense'"),
        ("rllib:/tmp/does-not-exist", "not found"),
        ("no_colon", "expected KIND:TARGET"),
        ("builtin:", "expected KIND:TARGET"),
        ("builtin:teleporter", "unknown (known: random, wall_follower)"),
        ("builtin:random?colour=red", "unknown option(s) colour"),
        ("builtin:random?actions", "not KEY=VALUE"),
        ("builtin:random?actions=x", "not an integer"),
        ("builtin:random?actions=9", "must be <= 7"),
        ("builtin:random?actions=3&actions=4", "given twice"),
    ],
)
def test_bad_specs(spec, needle):
    assert needle in str(load_error(spec))


def test_register_new_kind_without_touching_others(monkeypatch):
    # The kind lives in this process's registry: gone after the test, so other tests see the usual kinds.
    monkeypatch.setattr(agent_registry, "REGISTERED", {})
    class Constant(Agent):
        def initial_state(self, batch_size):
            return None

        def act(self, obs, state, rng):
            return np.full(len(obs["direction"]), 2, dtype=np.int64), state

    register_agent_kind("const_for_test", lambda target, options: Constant())
    agent = load_maze_agent("const_for_test:anything")
    assert agent.spec == "const_for_test:anything"
    with pytest.raises(ValueError):
        register_agent_kind("not a prefix", lambda target, options: Constant())
