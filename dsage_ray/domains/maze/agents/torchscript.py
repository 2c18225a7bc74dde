"""The Maze's TorchScript convention (``torchscript:PATH`` in the Maze): MiniGrid's view and heading as two inputs.

Any architecture, no Python class needed; the gym domain's ``torchscript:`` kind (``forward(obs)``,
:mod:`dsage_ray.agents.torchscript`) is the generic one, this is the MiniGrid-specific one the Maze registers.

Calling convention (one of two, detected when loading):

* **Stateless**: ``forward(image, direction) -> logits``.
* **Recurrent**: the module has an integer attribute ``state_size`` and
  ``forward(image, direction, state) -> (logits, next_state)``. ``state`` is one float32 tensor
  ``(n, state_size)``, all zeros at the start of an episode; pack several recurrent tensors (e.g. an LSTM's
  ``h`` and ``c``) into it.

In both, ``image`` is MiniGrid's egocentric view as float32 ``(n, 5, 5, 3)`` indexed ``[x, y, channel]``
with the raw encoding values (not rescaled: the module does its own preprocessing, so an export is
self-contained), ``direction`` is the heading as int64 ``(n,)``, and ``logits`` are float ``(n, k)`` with
``1 <= k <= 7`` over MiniGrid's first ``k`` actions. Actions are sampled from ``softmax(logits)`` with the
caller's ``rng``.

Detection: ``state_size`` selects the recurrent convention; either way the module is called once on a dummy
batch of two when loading, and a module that fails that call or returns the wrong shapes is rejected with an
:class:`~dsage_ray.agents.base.AgentError`.
"""

from __future__ import annotations

import pathlib

import numpy as np
import torch

from dsage_ray.agents.base import Agent, AgentError, AgentState, Observation
from dsage_ray.agents.loader import SpecOptions, describe_exception, require_file
from dsage_ray.agents.sampling import sample_from_logits
from dsage_ray.agents.torchscript import load_script_module
from dsage_ray.domains.maze.agents.constants import NUM_ACTIONS


class MazeTorchScriptAgent(Agent):
    """Wraps a loaded TorchScript policy; state is ``None`` (stateless) or a ``(n, state_size)`` tensor.

    Args:
        module: The scripted module, following the convention in the module docstring.
        state_size: Width of the recurrent state, or ``None`` for a stateless module.
    """

    def __init__(self, *, module: torch.jit.ScriptModule, state_size: int | None) -> None:
        self.module = module.eval()
        self.state_size = state_size

    def initial_state(self, batch_size: int) -> AgentState:
        return None if self.state_size is None else torch.zeros(batch_size, self.state_size)

    def logits(self, obs: Observation, state: AgentState) -> tuple[torch.Tensor, AgentState]:
        """One call of the module: logits ``(n, k)`` and the next state; no sampling."""
        with torch.inference_mode():
            image = torch.from_numpy(np.ascontiguousarray(obs["image"])).float()
            direction = torch.from_numpy(np.asarray(obs["direction"], dtype=np.int64))
            if self.state_size is None:
                return self.module(image, direction), None
            logits, state = self.module(image, direction, state)
            return logits, state

    def act(self, obs: Observation, state: AgentState, rng: np.random.Generator) -> tuple[np.ndarray, AgentState]:
        logits, state = self.logits(obs, state)
        return sample_from_logits(logits, rng), state


def load_torchscript_agent(target: str, options: SpecOptions) -> MazeTorchScriptAgent:
    """Factory for ``torchscript:PATH``; checks the calling convention with one dummy call."""
    path = require_file(target, what="torchscript file")
    module = load_script_module(path)
    state_size = _state_size(module, path)
    agent = MazeTorchScriptAgent(module=module, state_size=state_size)
    _check_convention(agent, path)
    return agent


def _state_size(module: torch.jit.ScriptModule, path: pathlib.Path) -> int | None:
    if not hasattr(module, "state_size"):
        return None
    size = getattr(module, "state_size")
    if isinstance(size, bool) or not isinstance(size, int) or size < 1:
        raise AgentError(f"torchscript file {str(path)!r}: state_size must be a positive int, got {size!r}")
    return size


def _check_convention(agent: MazeTorchScriptAgent, path: pathlib.Path) -> None:
    n = 2
    obs = {"image": np.ones((n, 5, 5, 3), dtype=np.uint8), "direction": np.arange(n, dtype=np.int64)}
    kind = "stateless forward(image, direction)" if agent.state_size is None else (
        f"recurrent forward(image, direction, state[n, {agent.state_size}])"
    )
    try:
        logits, state = agent.logits(obs, agent.initial_state(n))
    except Exception as exc:
        raise AgentError(f"torchscript file {str(path)!r}: calling it as {kind} failed ({describe_exception(exc)})") from None
    if not isinstance(logits, torch.Tensor) or logits.dim() != 2 or logits.shape[0] != n:
        raise AgentError(f"torchscript file {str(path)!r}: {kind} must return logits of shape (n, k)")
    if not 1 <= logits.shape[1] <= NUM_ACTIONS:
        raise AgentError(f"torchscript file {str(path)!r}: logits have {logits.shape[1]} actions, "
                         f"expected 1..{NUM_ACTIONS}")
    if agent.state_size is not None and (
        not isinstance(state, torch.Tensor) or tuple(state.shape) != (n, agent.state_size)
    ):
        raise AgentError(f"torchscript file {str(path)!r}: {kind} must return a next state of shape (n, state_size)")
