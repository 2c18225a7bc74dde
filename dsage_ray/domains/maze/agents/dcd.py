"""The DCD/ACCEL MiniGrid policy (``dcd:PATH``), loaded from its ``model.tar`` state_dict.

``dcd:accel`` loads the ACCEL checkpoint shipped with the package (``dsage_ray/assets/agents/accel/``: the DSAGE
authors' agent, MIT-licensed, sha256-verified on load); any other target is a checkpoint path.

The network (SPEC: the Maze) is rebuilt here with the checkpoint's exact parameter names so the weights load with
strict key matching::

    image (n, 5, 5, 3) uint8, indexed [x, y, channel]
      -> / 10, transposed to (n, 3, x, y)       # what DCD's image-preprocessing wrapper fed the network
      -> image_conv.0  Conv2d(3->16, k3, valid) -> flatten (144) -> ReLU
    direction (n,) -> one-hot (4) -> scalar_embed Linear(4->5)
    concat (149) -> rnn.rnn LSTM(149->256, one layer)
      -> actor.0.0 Linear(256->32) + Tanh -> actor.1.linear Linear(32->7) -> logits -> sampled action
      (critic.0.0 / critic.1: the value head; loaded for strictness, never evaluated)

Inference runs one step at a time on matrices precomputed from those weights (:class:`_StepWeights`), because
at evaluation batch sizes (≤ 50 rows) per-call overhead, not arithmetic, dominates (SPEC: speed): the conv becomes
one (75→144) matmul, the heading embedding and both LSTM biases one table row per heading one-hot, and each LSTM
step two ``addmm`` into one gate buffer. It is the same network with float32 sums taken in a different order,
so logits match the module-by-module computation to ~1e-6, not bit for bit (``tests/domains/maze/agents/test_dcd_step.py``
checks both that and that the real checkpoint takes the same actions on test mazes). Actions are sampled in
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

import copy
import pathlib
from typing import Any, Mapping

import numpy as np
import torch
from torch import nn

from dsage_ray.agents.base import Agent, AgentError, AgentState, Observation
from dsage_ray.agents.loader import (CHECKSUMS_FILE, SpecOptions, describe_exception, require_file, shipped_agent_dir,
                                     shipped_agent_names, verified_files)
from dsage_ray.agents.sampling import sample_from_logits
from dsage_ray.domains.maze.agents.constants import NUM_ACTIONS, NUM_HEADINGS

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


def _masks_to_onehot(masks: np.ndarray) -> np.ndarray:
    """4-bit heading masks ``(n,)`` (bit d set = heading d present) -> the network's heading input ``(n, 4)`` float32."""
    return ((masks[:, None] >> np.arange(NUM_HEADINGS)) & 1).astype(np.float32)


class _StepWeights:
    """The network's weights rearranged for one batched inference step (module docstring); built once per agent.

    Attributes:
        conv: ``(75, 144)``: row k is ``image_conv.0``'s (bias-free, flattened) response to the k-th unit image in
            MiniGrid's flat ``[x, y, channel]`` order. The conv is linear, so ``image.reshape(n, 75) @ conv +
            conv_bias`` is the conv on the transposed image, and each entry is one conv weight exactly.
        conv_bias: ``(144,)``, the conv bias repeated per output position.
        gate_bias: ``(16, 1024)``: for each heading mask m, ``W_ih[:, 144:] @ scalar_embed(onehot(m)) + b_ih + b_hh``
            -- every part of the LSTM's gates that depends on neither the image nor the hidden state. A table over
            all 16 masks covers both the true one-hot and the quirk's unions.
        w_image: ``(144, 1024)`` = ``W_ih[:, :144]ᵀ``.  w_hidden: ``(256, 1024)`` = ``W_hhᵀ``.
        actor_w1, actor_b1, actor_w2, actor_b2: The actor's two layers, weights transposed for ``addmm``.

    Gate columns are reordered from PyTorch's (i, f, g, o) to (i, f, o, g) so one sigmoid covers three gates.
    """

    def __init__(self, net: DCDNetwork) -> None:
        conv = net.image_conv[0]
        lstm = net.rnn.rnn
        hidden = lstm.hidden_size
        gate_order = torch.cat([torch.arange(0, 2 * hidden), torch.arange(3 * hidden, 4 * hidden),
                                torch.arange(2 * hidden, 3 * hidden)])
        w_ih, w_hh = lstm.weight_ih_l0[gate_order], lstm.weight_hh_l0[gate_order]
        num_image = w_ih.shape[1] - net.scalar_embed.out_features  # 144
        with torch.no_grad():
            units = torch.eye(5 * 5 * 3).reshape(-1, 5, 5, 3).permute(0, 3, 1, 2)
            self.conv = nn.functional.conv2d(units, conv.weight).flatten(1).contiguous()
            self.conv_bias = conv.bias.repeat_interleave(self.conv.shape[1] // conv.out_channels)
            onehots = torch.from_numpy(_masks_to_onehot(np.arange(1 << NUM_HEADINGS)))
            embedded = net.scalar_embed(onehots)
            bias = (lstm.bias_ih_l0 + lstm.bias_hh_l0)[gate_order]
            self.gate_bias = (embedded @ w_ih[:, num_image:].T + bias).contiguous()
            self.w_image = w_ih[:, :num_image].T.contiguous()
            self.w_hidden = w_hh.T.contiguous()
            actor1, actor2 = net.actor[0][0], net.actor[1].linear
            self.actor_w1, self.actor_b1 = actor1.weight.T.contiguous(), actor1.bias.detach().clone()
            self.actor_w2, self.actor_b2 = actor2.weight.T.contiguous(), actor2.bias.detach().clone()
        self.dtype = torch.float32

    def to(self, dtype: torch.dtype) -> "_StepWeights":
        """A copy whose matrices are ``dtype`` (the LSTM cell state and the logits stay float32)."""
        other = copy.copy(self)
        for name, value in vars(self).items():
            if isinstance(value, torch.Tensor) and value.is_floating_point():
                setattr(other, name, value.to(dtype))
        other.dtype = dtype
        return other


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
        self._step = _StepWeights(network)

    def reduced_precision(self) -> "DCDAgent":
        """This policy with its matrix products in bf16: about 3-4x faster where the CPU computes bf16
        natively (AVX512-BF16, AMX), and close to, not equal to, the agent (its rounding can flip a sampled
        action). For estimates only (``experimental.screen_precision``), never for a level's evaluation."""
        other = copy.copy(self)
        other._step = self._step.to(torch.bfloat16)
        return other

    def initial_state(self, batch_size: int) -> AgentState:
        zeros = torch.zeros(batch_size, HIDDEN_SIZE)
        return (zeros, zeros.clone())

    def heading_masks(self, direction: np.ndarray) -> np.ndarray:
        """The heading input ``(n,)`` int64 as 4-bit masks: ``1 << direction``, or the quirk's per-group union (OR).

        A true one-hot is the quirk with groups of one row, so both go through the same code.
        """
        bits = np.left_shift(1, np.asarray(direction, dtype=np.int64))
        n = len(bits)
        group_size = (self.quirk_group or max(n, 1)) if self.heading_quirk else 1
        if group_size == 1:
            return bits
        starts = np.arange(0, n, group_size)
        return np.repeat(np.bitwise_or.reduceat(bits, starts), np.diff(starts, append=n))

    def heading_onehot(self, direction: np.ndarray) -> np.ndarray:
        """The heading input ``(n, 4)`` float32 that the network sees: :meth:`heading_masks` as one-hot rows."""
        return _masks_to_onehot(self.heading_masks(direction))

    def logits(self, obs: Observation, state: AgentState) -> tuple[torch.Tensor, AgentState]:
        """One network step: action logits ``(n, 7)`` and the next ``(h, c)``; no sampling."""
        w = self._step
        h, c = state
        masks = torch.from_numpy(self.heading_masks(obs["direction"]))
        image = np.ascontiguousarray(obs["image"]).reshape(len(masks), -1)
        with torch.inference_mode():
            # MiniGrid's image is [x, y, channel] uint8; DCD scaled it by 1/10 (w.conv absorbs the transpose).
            features = torch.addmm(w.conv_bias, torch.from_numpy(image).to(w.dtype) / 10.0, w.conv).relu_()
            gates = w.gate_bias.index_select(0, masks).addmm_(features, w.w_image).addmm_(h.to(w.dtype), w.w_hidden)
            gates = gates.float()
            # nn.LSTM's cell equations, gates in (i, f, o, g) order.
            sig = gates[:, : 3 * HIDDEN_SIZE].sigmoid()
            i, f, o = sig[:, :HIDDEN_SIZE], sig[:, HIDDEN_SIZE : 2 * HIDDEN_SIZE], sig[:, 2 * HIDDEN_SIZE :]
            c = f * c + i * gates[:, 3 * HIDDEN_SIZE :].tanh()
            h = o * c.tanh()
            hidden = torch.addmm(w.actor_b1, h.to(w.dtype), w.actor_w1).tanh_()
            logits = torch.addmm(w.actor_b2, hidden, w.actor_w2).float()
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
    """Factory for ``dcd:PATH[?heading_quirk=0|1&quirk_group=N]``; ``dcd:NAME`` is a shipped checkpoint."""
    heading_quirk = options.get_bool("heading_quirk", False)
    quirk_group = options.get_int("quirk_group", 10, minimum=0)
    path = resolve_dcd_checkpoint(target)
    network = build_dcd_network(load_dcd_state_dict(path), source=str(path))
    return DCDAgent(network=network, heading_quirk=heading_quirk, quirk_group=quirk_group)


def resolve_dcd_checkpoint(target: str) -> pathlib.Path:
    """The checkpoint file ``target`` names: a path, or the one sha256-verified ``.tar`` of a shipped agent.

    Raises:
        AgentError: A missing file (naming the shipped checkpoints when ``target`` is a bare name), a shipped
            agent that is not a dcd checkpoint, or a shipped file that fails its checksum.
    """
    folder = shipped_agent_dir(target)
    if folder is None:
        try:
            return require_file(target, what="dcd checkpoint")
        except AgentError as exc:
            shipped = shipped_agent_names(holding="*.tar")
            if "/" in target or not shipped:
                raise
            raise AgentError(f"{exc} (shipped: {', '.join(f'dcd:{name}' for name in shipped)})") from None
    what = f"dcd checkpoint {target!r}"
    if not (folder / CHECKSUMS_FILE).is_file():
        raise AgentError(f"{what}: the shipped agent {target!r} is not a dcd checkpoint (no {CHECKSUMS_FILE})")
    checkpoints = [path for path in verified_files(folder, what=what) if path.suffix == ".tar"]
    if len(checkpoints) != 1:
        raise AgentError(f"{what}: {CHECKSUMS_FILE} lists {len(checkpoints)} .tar checkpoints, expected 1")
    return checkpoints[0]


def _is_state_dict(blob: Mapping) -> bool:
    return len(blob) > 0 and all(isinstance(k, str) and isinstance(v, torch.Tensor) for k, v in blob.items())


def _short_list(keys: list[str], limit: int = 4) -> str:
    shown = ", ".join(keys[:limit])
    return shown + (f" (+{len(keys) - limit} more)" if len(keys) > limit else "")

