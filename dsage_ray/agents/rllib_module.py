"""The project's RLlib policy for the Maze: a small CNN over the egocentric view, optionally recurrent.

``MazeRLModule`` is a new-API-stack :class:`~ray.rllib.core.rl_module.torch.TorchRLModule`. RLlib saves
its class path in every checkpoint and re-imports it when loading, so it lives in the package (not in the
training script) to stay importable wherever a checkpoint is loaded.

Observation: ``{"image": Box(0, 255, (5, 5, 3), uint8), "direction": Discrete(4)}`` — MiniGrid's
observation without the mission string (:data:`MAZE_OBSERVATION_SPACE`). Network::

    image (B, 5, 5, 3) [x, y, (object, colour, state)]
      -> object channel one-hot (11 MiniGrid object kinds) ++ colour/10 ++ state/10   (13 channels)
      -> Conv3x3(13->32) ReLU -> Conv3x3(32->64) ReLU -> flatten (64)
    direction -> Embedding(4, 8)
    concat (72) -> Linear(72->hidden) ReLU [-> LSTM(hidden->hidden)] -> policy head (7 logits), value head

The object one-hot matters: raw object indices (1 empty, 2 wall, 8 goal) put the goal "between" nothing
and everything, which a conv learns slowly; a one-hot makes "goal here" one input bit.

``model_config`` keys: ``hidden`` (default 128), ``use_lstm`` (default False).

The module is built through RLlib 2.60's current constructor, ``MazeRLModule(observation_space=..,
action_space=.., inference_only=.., learner_only=.., model_config=.., catalog_class=..)``: it only
overrides :meth:`~MazeRLModule.setup`, as RLlib asks, and its checkpoints record those keyword arguments.
"""

from __future__ import annotations

import logging
from typing import Any

import gymnasium as gym
import numpy as np
import torch
from minigrid.core.actions import Actions
from minigrid.core.constants import DIR_TO_VEC, OBJECT_TO_IDX
from ray.rllib.core.columns import Columns
from ray.rllib.core.rl_module.apis.value_function_api import ValueFunctionAPI
from ray.rllib.core.rl_module.torch import TorchRLModule
from torch import nn


# MiniGrid's sizes, read from MiniGrid itself. This module stays in the agent layer, not with the Maze's agents
# (dsage_ray.domains.maze.agents), because every checkpoint records its class by this import path; it therefore
# imports no domain, and tests/domains/maze/agents/test_constants.py checks these equal the Maze's.
NUM_OBJECT_KINDS = len(OBJECT_TO_IDX)
NUM_HEADINGS = len(DIR_TO_VEC)
VIEW_SIZE = 5
#: The observation every maze policy sees (MiniGrid's dict minus ``mission``).
MAZE_OBSERVATION_SPACE = gym.spaces.Dict({
    "direction": gym.spaces.Discrete(NUM_HEADINGS),
    "image": gym.spaces.Box(0, 255, (VIEW_SIZE, VIEW_SIZE, 3), np.uint8),
})
MAZE_ACTION_SPACE = gym.spaces.Discrete(len(Actions))

#: What RLlib 2.60 logs once per process on the first RLModule it builds, whatever constructor was used.
_RLMODULE_CONFIG_WARNING = "`RLModule(config=[RLModuleConfig object])` has been deprecated"


class _DropRLModuleConfigWarning(logging.Filter):
    """Drops RLlib's warning that ``RLModule(config=RLModuleConfig)`` is deprecated, and nothing else.

    ``RLModule.__init__`` itself builds an ``RLModuleConfig`` for old subclasses on every construction, so the
    warning appears even for modules built through the current keyword constructor (like every module here);
    a real ``config=`` call is an error in this RLlib, so the warning never tells the user anything.
    """

    def filter(self, record: logging.LogRecord) -> bool:
        return _RLMODULE_CONFIG_WARNING not in record.getMessage()


def drop_rlmodule_config_warning() -> None:
    """Installs :class:`_DropRLModuleConfigWarning` on RLlib's deprecation logger (idempotent)."""
    logger = logging.getLogger("ray._common.deprecation")
    if not any(isinstance(f, _DropRLModuleConfigWarning) for f in logger.filters):
        logger.addFilter(_DropRLModuleConfigWarning())


# At import: RLlib imports this module (from the class path in a checkpoint or a spec) before building one.
drop_rlmodule_config_warning()


class MazeRLModule(TorchRLModule, ValueFunctionAPI):
    """Actor-critic for the Maze's 5×5 egocentric view (module docstring for the architecture).

    Built by RLlib from an ``RLModuleSpec(module_class=MazeRLModule, model_config={...})``; with
    ``use_lstm`` the module is stateful and RLlib feeds it ``(B, T, ...)`` sequences.
    """

    def setup(self) -> None:
        self.hidden = int(self.model_config.get("hidden", 128))
        self.use_lstm = bool(self.model_config.get("use_lstm", False))
        in_channels = NUM_OBJECT_KINDS + 2
        self.conv = nn.Sequential(
            nn.Conv2d(in_channels, 32, kernel_size=3), nn.ReLU(),
            nn.Conv2d(32, 64, kernel_size=3), nn.ReLU(),
            nn.Flatten(),
        )
        self.direction_embed = nn.Embedding(NUM_HEADINGS, 8)
        self.trunk = nn.Sequential(nn.Linear(64 + 8, self.hidden), nn.ReLU())
        self.lstm = nn.LSTM(self.hidden, self.hidden, batch_first=True) if self.use_lstm else None
        self.pi = nn.Linear(self.hidden, self.action_space.n)
        self.vf = nn.Linear(self.hidden, 1)

    def get_initial_state(self) -> dict[str, np.ndarray]:
        if not self.use_lstm:
            return {}
        zeros = np.zeros(self.hidden, dtype=np.float32)
        return {"h": zeros, "c": zeros.copy()}

    # ------------------------------------------------------------------------------ forward passes

    def _forward(self, batch: dict[str, Any], **kwargs) -> dict[str, Any]:
        embeddings, state_out = self._embed(batch)
        out = {Columns.ACTION_DIST_INPUTS: self.pi(embeddings)}
        if state_out is not None:
            out[Columns.STATE_OUT] = state_out
        return out

    def _forward_train(self, batch: dict[str, Any], **kwargs) -> dict[str, Any]:
        embeddings, state_out = self._embed(batch)
        out = {Columns.ACTION_DIST_INPUTS: self.pi(embeddings), Columns.EMBEDDINGS: embeddings}
        if state_out is not None:
            out[Columns.STATE_OUT] = state_out
        return out

    def compute_values(self, batch: dict[str, Any], embeddings: Any = None) -> torch.Tensor:
        if embeddings is None:
            embeddings, _ = self._embed(batch)
        return self.vf(embeddings).squeeze(-1)

    # ----------------------------------------------------------------------------------- helpers

    def _embed(self, batch: dict[str, Any]) -> tuple[torch.Tensor, dict[str, torch.Tensor] | None]:
        """Per-step features ``(B, hidden)`` (``(B, T, hidden)`` with the LSTM) and the next state."""
        obs = batch[Columns.OBS]
        image, direction = torch.as_tensor(obs["image"]), torch.as_tensor(obs["direction"]).long()
        lead = image.shape[:-3]  # (B,) or (B, T)
        features = self.trunk(torch.cat([
            self.conv(encode_image(image.reshape(-1, VIEW_SIZE, VIEW_SIZE, 3))),
            self.direction_embed(direction.reshape(-1)),
        ], dim=-1)).reshape(*lead, self.hidden)
        if self.lstm is None:
            return features, None
        state = batch[Columns.STATE_IN]
        out, (h, c) = self.lstm(features, (state["h"].unsqueeze(0), state["c"].unsqueeze(0)))
        return out, {"h": h.squeeze(0), "c": c.squeeze(0)}


def encode_image(image: torch.Tensor) -> torch.Tensor:
    """``(N, 5, 5, 3)`` MiniGrid encodings → ``(N, 13, 5, 5)`` float network input (channels first)."""
    objects = nn.functional.one_hot(image[..., 0].long().clamp(0, NUM_OBJECT_KINDS - 1), NUM_OBJECT_KINDS)
    rest = image[..., 1:].float() / 10.0
    return torch.cat([objects.float(), rest], dim=-1).permute(0, 3, 1, 2)
