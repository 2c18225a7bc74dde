"""``torchscript:PATH`` with the Maze's convention (torchscript.py): a scripted module maps the MiniGrid view and
heading to action logits, optionally with a state; a file that is not one fails with one clear line."""

from __future__ import annotations

import numpy as np
import torch
from torch import nn

from dsage_ray.domains.maze.agents import load_maze_agent
from dsage_ray.domains.maze.agents.torchscript import MazeTorchScriptAgent
from tests.domains.maze.agents.conftest import load_error


class _Stateless(nn.Module):
    def forward(self, image: torch.Tensor, direction: torch.Tensor) -> torch.Tensor:
        return image.reshape(image.shape[0], -1)[:, :7] + direction[:, None].float()


class _Recurrent(nn.Module):
    def __init__(self) -> None:
        super().__init__()
        self.state_size = 4

    def forward(self, image: torch.Tensor, direction: torch.Tensor, state: torch.Tensor):
        return torch.zeros(image.shape[0], 3) + state[:, :3], state + 1.0


class _WrongShape(nn.Module):
    def forward(self, image: torch.Tensor, direction: torch.Tensor) -> torch.Tensor:
        return torch.zeros(image.shape[0], 12)


def _script(module: nn.Module, path):
    torch.jit.script(module).save(str(path))
    return path


def test_torchscript_stateless_and_recurrent(tmp_path):
    stateless = load_maze_agent(f"torchscript:{_script(_Stateless(), tmp_path / 'a.pt')}")
    assert isinstance(stateless, MazeTorchScriptAgent) and stateless.state_size is None
    recurrent = load_maze_agent(f"torchscript:{_script(_Recurrent(), tmp_path / 'b.pt')}")
    assert recurrent.state_size == 4
    obs = {"image": np.zeros((3, 5, 5, 3), np.uint8), "direction": np.zeros(3, np.int64)}
    state = recurrent.initial_state(3)
    for _ in range(2):
        actions, state = recurrent.act(obs, state, np.random.default_rng(0))
    assert torch.equal(state, torch.full((3, 4), 2.0)) and actions.dtype == np.int64 and (actions < 3).all()


def test_torchscript_bad_files(tmp_path, random_dcd_checkpoint):
    garbage = tmp_path / "garbage.pt"
    garbage.write_bytes(b"\x00\x01 not torchscript")
    assert "not a TorchScript module" in str(load_error(f"torchscript:{garbage}"))
    # A valid zip checkpoint, but a state_dict rather than a scripted module.
    err = str(load_error(f"torchscript:{random_dcd_checkpoint}"))
    assert "model.tar" in err and "not a TorchScript module" in err
    err = str(load_error(f"torchscript:{_script(_WrongShape(), tmp_path / 'wide.pt')}"))
    assert "12 actions, expected 1..7" in err
    assert "file not found" in str(load_error(f"torchscript:{tmp_path / 'missing.pt'}"))
