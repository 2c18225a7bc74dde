"""The DCD/ACCEL MiniGrid policy (``dcd:PATH``), loaded from its ``model.tar`` state_dict.

The network (SPEC §2) is rebuilt here with the checkpoint's exact parameter names so the weights load with
strict key matching::

    image (n, 5, 5, 3) uint8, indexed [x, y, channel]
      -> / 10, transposed to (n, 3, x, y)       # what DCD's image-preprocessing wrapper fed the network
      -> image_conv.0  Conv2d(3->16, k3, valid) -> flatten (144) -> ReLU
    direction (n,) -> one-hot (4) -> scalar_embed Linear(4->5)
    concat (149) -> rnn.rnn LSTM(149->256, one layer)
      -> actor.0.0 Linear(256->32) + Tanh -> actor.1.linear Linear(32->7) -> logits -> sampled action
      (critic.0.0 / critic.1: the value head; loaded for strictness, never evaluated)

Inference runs one step at a time with an :class:`torch.nn.LSTMCell` that carries the LSTM's weights (same
gate order and equations as a one-step ``nn.LSTM``, less per-call overhead), and actions are sampled in
numpy from the caller's ``rng`` (:mod:`dsage_ray.agents.sampling`).

Options (``dcd:PATH?heading_quirk=1&quirk_group=10``):
    heading_quirk: 0 (default) feeds the correct heading one-hot. 1 reproduces the original code's
        ``onehot[:, headings] = 1``: every row of a batch gets a 1 at *every* heading present in the batch.
    quirk_group: With the quirk, which rows form one "batch" for the union: the rows passed to one
        :meth:`DCDAgent.act` call are split into consecutive groups of ``quirk_group`` rows (the last group may
        be shorter), and each row gets the union of headings within its group. The default 10 matches the
        original evaluation, which ran 50 episodes as 10 lock-stepped environments; 0 means the whole batch is
        one group. Groups are by position in the current batch: when finished episodes leave the batch
        (:meth:`~dsage_ray.agents.base.Agent.select_state`), the remaining rows regroup, just as a shrinking
        lock-stepped batch would.
"""

from __future__ import annotations

import pathlib
from typing import Any, Mapping

import numpy as np
import torch
from torch import nn

from dsage_ray.agents.base import Agent, AgentError, AgentState, Observation
from dsage_ray.agents.loader import SpecOptions, describe_exception, require_file
from dsage_ray.agents.sampling import sample_from_logits

NUM_HEADINGS = 4
NUM_ACTIONS = 7
HIDDEN_SIZE = 256
#: Keys under which training scripts commonly wrap a state_dict; the ACCEL checkpoint itself is bare.
_WRAPPER_KEYS = ("model_state_dict", "state_dict", "model")


class _CategoricalHead(nn.Module):
    """Holds the final actor layer under the name DCD's ``Categorical`` module used (``.linear``)."""

    def __init__(self, *, in_features: int, num_actions: int) -> None:
        super().__init__()
        self.linear = nn.Linear(in_features, num_actions)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.linear(x)  # logits; sampling happens in numpy


class _RNN(nn.Module):
    """Holds the LSTM under the name DCD's ``RNN`` wrapper used (``.rnn``)."""

    def __init__(self, *, input_size: int, hidden_size: int) -> None:
        super().__init__()
        self.rnn = nn.LSTM(input_size, hidden_size, num_layers=1)


class DCDNetwork(nn.Module):
    """The ACCEL MultiGrid actor-critic, with the checkpoint's parameter names; used for loading only."""

    def __init__(self) -> None:
        super().__init__()
        self.image_conv = nn.Sequential(nn.Conv2d(3, 16, kernel_size=3), nn.Flatten(), nn.ReLU())
        self.scalar_embed = nn.Linear(NUM_HEADINGS, 5)
        self.rnn = _RNN(input_size=16 * 3 * 3 + 5, hidden_size=HIDDEN_SIZE)
        self.actor = nn.Sequential(
            nn.Sequential(nn.Linear(HIDDEN_SIZE, 32), nn.Tanh()),
            _CategoricalHead(in_features=32, num_actions=NUM_ACTIONS),
        )
        self.critic = nn.Sequential(nn.Sequential(nn.Linear(HIDDEN_SIZE, 32), nn.Tanh()), nn.Linear(32, 1))


class DCDAgent(Agent):
    """A recurrent, stochastic ACCEL policy; its state is the LSTM's ``(h, c)``, each ``(n, 256)`` float32.

    Args:
        network: A :class:`DCDNetwork` with its weights loaded.
        heading_quirk: Reproduce the original ``onehot[:, headings] = 1`` heading encoding (module docstring).
        quirk_group: Rows per group for the quirk's union; 0 = the whole batch. Ignored without the quirk.
    """

    def __init__(self, *, network: DCDNetwork, heading_quirk: bool = False, quirk_group: int = 10) -> None:
        if quirk_group < 0:
            raise ValueError(f"quirk_group must be >= 0, got {quirk_group}")
        self.network = network.eval()
        self.heading_quirk = heading_quirk
        self.quirk_group = quirk_group
        lstm = network.rnn.rnn
        self._cell = nn.LSTMCell(lstm.input_size, lstm.hidden_size)
        with torch.no_grad():
            self._cell.weight_ih.copy_(lstm.weight_ih_l0)
            self._cell.weight_hh.copy_(lstm.weight_hh_l0)
            self._cell.bias_ih.copy_(lstm.bias_ih_l0)
            self._cell.bias_hh.copy_(lstm.bias_hh_l0)
        self._cell.eval()

    def initial_state(self, batch_size: int) -> AgentState:
        zeros = torch.zeros(batch_size, HIDDEN_SIZE)
        return (zeros, zeros.clone())

    def heading_onehot(self, direction: np.ndarray) -> np.ndarray:
        """The heading input ``(n, 4)`` float32: a true one-hot, or the quirk's per-group union.

        A true one-hot is the quirk with groups of one row, so both go through the same code.
        """
        n = len(direction)
        group_size = (self.quirk_group or max(n, 1)) if self.heading_quirk else 1
        group = np.arange(n) // group_size
        present = np.zeros((group[-1] + 1 if n else 0, NUM_HEADINGS), dtype=np.float32)
        present[group, direction] = 1.0
        return present[group]

    def logits(self, obs: Observation, state: AgentState) -> tuple[torch.Tensor, AgentState]:
        """One network step: action logits ``(n, 7)`` and the next ``(h, c)``; no sampling."""
        net = self.network
        direction = np.asarray(obs["direction"], dtype=np.int64)
        with torch.inference_mode():
            # MiniGrid's image is [x, y, channel]; DCD scaled it by 1/10 and moved channels first -> (3, x, y).
            image = torch.from_numpy(np.ascontiguousarray(obs["image"])).permute(0, 3, 1, 2).float() / 10.0
            in_image = net.image_conv(image)
            in_scalar = net.scalar_embed(torch.from_numpy(self.heading_onehot(direction)))
            h, c = self._cell(torch.cat((in_image, in_scalar), dim=1), state)
            logits = net.actor(h)
        return logits, (h, c)

    def act(self, obs: Observation, state: AgentState, rng: np.random.Generator) -> tuple[np.ndarray, AgentState]:
        logits, state = self.logits(obs, state)
        return sample_from_logits(logits, rng), state


def load_dcd_state_dict(path: pathlib.Path) -> dict[str, torch.Tensor]:
    """Reads a DCD checkpoint: a bare state_dict, or one wrapped under a common key; AgentError otherwise."""
    try:
        blob: Any = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as exc:  # torch raises many types for non-checkpoints (RuntimeError, UnpicklingError, EOF...)
        raise AgentError(f"dcd checkpoint {str(path)!r}: not a readable PyTorch checkpoint ({describe_exception(exc)})") from None
    if isinstance(blob, Mapping) and not _is_state_dict(blob):
        for key in _WRAPPER_KEYS:
            if isinstance(blob.get(key), Mapping):
                blob = blob[key]
                break
    if not isinstance(blob, Mapping) or not _is_state_dict(blob):
        raise AgentError(f"dcd checkpoint {str(path)!r}: holds a {type(blob).__name__}, not a state_dict of tensors")
    return dict(blob)


def build_dcd_network(state_dict: Mapping[str, torch.Tensor], *, source: str) -> DCDNetwork:
    """A :class:`DCDNetwork` with ``state_dict`` loaded strictly; key or shape mismatches raise AgentError."""
    network = DCDNetwork()
    expected = network.state_dict()
    missing = sorted(set(expected) - set(state_dict))
    unexpected = sorted(set(state_dict) - set(expected))
    if missing or unexpected:
        parts = []
        if missing:
            parts.append(f"missing keys {_short_list(missing)}")
        if unexpected:
            parts.append(f"unexpected keys {_short_list(unexpected)}")
        raise AgentError(f"dcd checkpoint {source!r}: not the ACCEL MultiGrid network: {'; '.join(parts)}")
    for key, tensor in expected.items():
        if tuple(state_dict[key].shape) != tuple(tensor.shape):
            raise AgentError(
                f"dcd checkpoint {source!r}: {key} has shape {tuple(state_dict[key].shape)}, expected {tuple(tensor.shape)}"
            )
    network.load_state_dict(state_dict, strict=True)
    return network


def load_dcd_agent(target: str, options: SpecOptions) -> DCDAgent:
    """Factory for ``dcd:PATH[?heading_quirk=0|1&quirk_group=N]``."""
    heading_quirk = options.get_bool("heading_quirk", False)
    quirk_group = options.get_int("quirk_group", 10, minimum=0)
    path = require_file(target, what="dcd checkpoint")
    network = build_dcd_network(load_dcd_state_dict(path), source=str(path))
    return DCDAgent(network=network, heading_quirk=heading_quirk, quirk_group=quirk_group)


def _is_state_dict(blob: Mapping) -> bool:
    return len(blob) > 0 and all(isinstance(k, str) and isinstance(v, torch.Tensor) for k, v in blob.items())


def _short_list(keys: list[str], limit: int = 4) -> str:
    shown = ", ".join(keys[:limit])
    return shown + (f" (+{len(keys) - limit} more)" if len(keys) > limit else "")

