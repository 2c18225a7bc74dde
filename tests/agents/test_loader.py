"""Spec parsing and loading: good files load, bad ones fail with one clear line naming the file."""

from __future__ import annotations

import hashlib
import pickle
import shutil

import numpy as np
import pytest
import torch
from torch import nn

from dsage_ray import agent_registry
from dsage_ray.agents import Agent, AgentError, loader, register_agent_kind
from dsage_ray.domains.maze.agents import load_maze_agent
from dsage_ray.domains.maze.agents.builtin import RandomAgent, WallFollowerAgent
from dsage_ray.domains.maze.agents.dcd import DCDAgent, DCDNetwork
from dsage_ray.agents.loader import ASSETS_DIR
from dsage_ray.domains.maze.agents.torchscript import MazeTorchScriptAgent
from tests.agents.conftest import shared_dir
from tests.domains.maze.agents.conftest import ACCEL_SPEC, accel_checkpoint, random_dcd_checkpoint  # noqa: F401 - fixtures

#: The published ACCEL checkpoint (SPEC §2: sha256 5ad0ce09…634ae).
ACCEL_SHA256 = "5ad0ce09ce1f1763f4b2c16f2ec08da1abb6a0564b0cf715e9be4c0ac7a634ae"


def load_error(spec: str) -> AgentError:
    with pytest.raises(AgentError) as info:
        load_maze_agent(spec)
    err = info.value
    assert "\n" not in str(err), f"multi-line error: {err}"
    assert err.__cause__ is None and err.__suppress_context__ or err.__context__ is None, "torch traceback leaked"
    return err


# --- spec syntax --------------------------------------------------------------------------------------------


def test_builtin_specs_load_and_record_spec():
    assert isinstance(load_maze_agent("builtin:random"), RandomAgent)
    agent = load_maze_agent("builtin:wall_follower")
    assert isinstance(agent, WallFollowerAgent) and agent.spec == "builtin:wall_follower"
    assert load_maze_agent("builtin:random?actions=7").num_actions == 7


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


# --- dcd files ----------------------------------------------------------------------------------------------


def test_dcd_loads_bare_and_wrapped_state_dicts(random_dcd_checkpoint, tmp_path):
    assert isinstance(load_maze_agent(f"dcd:{random_dcd_checkpoint}"), DCDAgent)
    wrapped = tmp_path / "wrapped.tar"
    torch.save({"model_state_dict": torch.load(random_dcd_checkpoint), "num_updates": 3}, wrapped)
    assert isinstance(load_maze_agent(f"dcd:{wrapped}"), DCDAgent)


def test_dcd_options(random_dcd_checkpoint):
    agent = load_maze_agent(f"dcd:{random_dcd_checkpoint}?heading_quirk=1&quirk_group=5")
    assert agent.heading_quirk and agent.quirk_group == 5
    assert "not a boolean" in str(load_error(f"dcd:{random_dcd_checkpoint}?heading_quirk=maybe"))
    assert "unknown option(s) temperature" in str(load_error(f"dcd:{random_dcd_checkpoint}?temperature=2"))


def test_dcd_missing_file_and_directory(tmp_path):
    err = load_error(f"dcd:{tmp_path / 'nope.tar'}")
    assert "nope.tar" in str(err) and "file not found" in str(err)
    assert "not a regular file" in str(load_error(f"dcd:{tmp_path}"))


def test_dcd_garbage_file(tmp_path):
    path = tmp_path / "garbage.tar"
    path.write_bytes(b"this is not a checkpoint at all\n" * 10)
    err = load_error(f"dcd:{path}")
    assert "garbage.tar" in str(err) and "not a readable PyTorch checkpoint" in str(err)


def test_dcd_truncated_file(random_dcd_checkpoint):
    data = random_dcd_checkpoint.read_bytes()
    random_dcd_checkpoint.write_bytes(data[: len(data) // 2])
    err = load_error(f"dcd:{random_dcd_checkpoint}")
    assert "model.tar" in str(err) and "not a readable PyTorch checkpoint" in str(err)


def test_dcd_pickle_with_foreign_objects_is_rejected_not_executed(tmp_path):
    path = tmp_path / "evil.tar"
    path.write_bytes(pickle.dumps({"image_conv.0.weight": np.zeros(3)}))  # numpy global: refused by weights_only
    assert "not a readable PyTorch checkpoint" in str(load_error(f"dcd:{path}"))


class _RunsShell:
    def __reduce__(self):
        import os

        return os.system, ("true",)


def test_a_dcd_file_holding_code_is_refused_without_torchs_advice_to_run_it(tmp_path):
    path = tmp_path / "evil.tar"
    torch.save({"image_conv.0.weight": _RunsShell()}, path)
    message = str(load_error(f"dcd:{path}"))
    assert "GLOBAL posix.system" in message and "read as data only; nothing in it ran" in message
    assert "weights_only" not in message and "\n" not in message


def test_dcd_not_a_state_dict(tmp_path):
    path = tmp_path / "tensor.tar"
    torch.save(torch.zeros(3), path)
    assert "holds a Tensor, not a state_dict" in str(load_error(f"dcd:{path}"))


def test_dcd_wrong_keys(tmp_path):
    path = tmp_path / "mlp.tar"
    torch.save(nn.Sequential(nn.Linear(4, 4)).state_dict(), path)
    err = str(load_error(f"dcd:{path}"))
    assert "mlp.tar" in err and "missing keys" in err and "unexpected keys 0.bias, 0.weight" in err


def test_dcd_extra_key_fails_strict_matching(random_dcd_checkpoint):
    state = torch.load(random_dcd_checkpoint)
    state["actor.2.weight"] = torch.zeros(1)
    torch.save(state, random_dcd_checkpoint)
    assert "unexpected keys actor.2.weight" in str(load_error(f"dcd:{random_dcd_checkpoint}"))


def test_dcd_wrong_shape(random_dcd_checkpoint):
    state = torch.load(random_dcd_checkpoint)
    state["actor.1.linear.weight"] = torch.zeros(3, 32)  # a 3-action head
    torch.save(state, random_dcd_checkpoint)
    err = str(load_error(f"dcd:{random_dcd_checkpoint}"))
    assert "actor.1.linear.weight has shape (3, 32), expected (7, 32)" in err


def test_real_accel_checkpoint_loads_strictly(accel_checkpoint):
    state = torch.load(accel_checkpoint, map_location="cpu", weights_only=True)
    assert set(state) == set(DCDNetwork().state_dict()), "the real file is a bare state_dict with exactly our keys"
    agent = load_maze_agent(ACCEL_SPEC)
    assert agent.spec == ACCEL_SPEC
    for key, tensor in agent.network.state_dict().items():
        assert torch.equal(tensor, state[key])


# --- shipped agents -----------------------------------------------------------------------------------------


def test_shipped_accel_is_the_published_file_with_its_notice():
    folder = ASSETS_DIR / "accel"
    assert hashlib.sha256((folder / "model_20000.tar").read_bytes()).hexdigest() == ACCEL_SHA256
    assert f"{ACCEL_SHA256}  model_20000.tar" in (folder / "SHA256SUMS").read_text()
    assert ACCEL_SHA256 in (folder / "README.md").read_text()
    license_text = (folder / "LICENSE").read_text()
    assert "MIT License" in license_text and "Copyright (c) 2022 ICAROS Lab" in license_text
    original = shared_dir() / "models" / "accel_seed_1" / "model_20000.tar"
    if original.is_file():  # optional: the authors' file as distributed beside the repository
        assert (folder / "model_20000.tar").read_bytes() == original.read_bytes()


@pytest.fixture
def assets_copy(tmp_path, monkeypatch):
    """A writable copy of the shipped agents, installed in place of the package's."""
    copy = tmp_path / "agents"
    shutil.copytree(ASSETS_DIR, copy)
    monkeypatch.setattr(loader, "ASSETS_DIR", copy)
    return copy


def test_corrupt_shipped_checkpoint_is_refused(assets_copy):
    checkpoint = assets_copy / "accel" / "model_20000.tar"
    data = bytearray(checkpoint.read_bytes())
    data[len(data) // 2] ^= 0x01  # one flipped bit in the weights: torch would load it without complaint
    checkpoint.write_bytes(bytes(data))
    err = str(load_error("dcd:accel"))
    assert "model_20000.tar" in err and "is corrupt" in err and ACCEL_SHA256 in err
    checkpoint.unlink()
    assert "cannot read" in str(load_error("dcd:accel"))
    (assets_copy / "accel" / "SHA256SUMS").write_text("not a checksum line\n")
    assert "is not '<sha256>  <file>'" in str(load_error("dcd:accel"))


def test_shipped_names_resolve_only_as_bare_names(assets_copy, tmp_path, monkeypatch):
    assert "file not found (shipped: dcd:accel)" in str(load_error("dcd:acel"))
    assert "not a dcd checkpoint" in str(load_error("dcd:ppo_maze"))
    assert "file not found" in str(load_error("dcd:./accel"))  # a path, not a name
    # A local file of the same name wins over the shipped agent: shipping never changes what a spec loads.
    monkeypatch.chdir(tmp_path)
    (tmp_path / "accel").write_bytes(b"not a checkpoint")
    assert "not a readable PyTorch checkpoint" in str(load_error("dcd:accel"))


# --- torchscript files --------------------------------------------------------------------------------------


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
