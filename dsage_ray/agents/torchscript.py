"""A policy exported as TorchScript (``torchscript:PATH``): any architecture, no Python class needed.

Calling convention: ``forward(obs)``, where ``obs`` is the :func:`~dsage_ray.agents.spaces.stack_observations`
batch as tensors (floats as float32; a Dict as a dict of tensors). It returns logits ``(n, k)`` for a
``Discrete(k)`` action space (actions are sampled from ``softmax(logits)`` with the caller's ``rng``) or actions
``(n, *shape)`` for a Box one (clipped to the bounds).

The Maze registers its own ``torchscript:`` kind, MiniGrid's view and heading as two inputs
(:mod:`dsage_ray.domains.maze.agents.torchscript`); both read the file with :func:`load_script_module`.
"""

from __future__ import annotations

import pathlib
import warnings
from typing import Any

import gymnasium
import numpy as np
import torch
from gymnasium import spaces

from dsage_ray.agents.base import Agent, AgentError, AgentState
from dsage_ray.agents.loader import SpecOptions, describe_exception, require_file
from dsage_ray.agents.spaces import categorical, finish_actions, require_discrete_or_box, to_torch


class TorchScriptAgent(Agent):
    """A scripted ``forward(obs)``: logits ``(n, k)`` for Discrete(k) (sampled), actions ``(n, *shape)`` for Box.

    Args:
        module: The scripted module.
        action_space: The environment's Discrete or Box action space.
    """

    def __init__(self, *, module: Any, action_space: gymnasium.Space) -> None:
        self.module = module.eval()
        self.action_space = action_space

    def initial_state(self, batch_size: int) -> AgentState:
        return None

    def act(self, obs: Any, state: AgentState, rng: np.random.Generator) -> tuple[np.ndarray, AgentState]:
        with torch.inference_mode():
            out = self.module(to_torch(obs))
        if not isinstance(out, torch.Tensor):
            raise AgentError(f"forward(obs) returned {type(out).__name__}, not a tensor")
        if isinstance(self.action_space, spaces.Discrete):
            return categorical(out, self.action_space, greedy=False, rng=rng), None
        return finish_actions(out.double().numpy(), self.action_space), None


def load_script_module(path: pathlib.Path) -> torch.jit.ScriptModule:
    """The TorchScript module in the file ``path``, on the CPU; AgentError when it holds none."""
    try:
        with warnings.catch_warnings():
            # torch 2.9+ marks TorchScript deprecated; the user asked for this format explicitly.
            warnings.simplefilter("ignore", DeprecationWarning)
            return torch.jit.load(str(path), map_location="cpu")
    except Exception as exc:  # torch reports non-TorchScript files as assorted RuntimeErrors
        raise AgentError(f"torchscript file {str(path)!r}: not a TorchScript module ({describe_exception(exc)})") from None


def load_torchscript(target: str, options: SpecOptions, *, action_space: gymnasium.Space) -> tuple[Agent, str]:
    """The agent ``torchscript:PATH`` names, acting in ``action_space``, and the label its errors start with."""
    path = require_file(target, what="torchscript file")
    label = f"torchscript file {str(path)!r}"
    require_discrete_or_box(action_space, label=label)
    return TorchScriptAgent(module=load_script_module(path), action_space=action_space), label
