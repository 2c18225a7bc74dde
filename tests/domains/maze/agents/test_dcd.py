"""The DCD/ACCEL agent (dcd.py): its mechanics on a random-weight checkpoint of the same format (no shared files
needed), its files (good ones load strictly, bad ones fail with one clear line naming the file), and the shipped
ACCEL checkpoint (``dcd:accel``: the published file, verified on every load)."""

from __future__ import annotations

import hashlib
import pickle
import shutil

import numpy as np
import pytest
import torch
from torch import nn

from dsage_ray.agents import loader
from dsage_ray.agents.loader import ASSETS_DIR
from dsage_ray.agents.sampling import sample_from_logits
from dsage_ray.domains.maze.agents import load_maze_agent
from dsage_ray.domains.maze.agents.dcd import DCDAgent, DCDNetwork
from tests.agents.conftest import shared_dir
from tests.domains.maze.agents.conftest import ACCEL_SPEC, load_error

#: The published ACCEL checkpoint (SPEC §2: sha256 5ad0ce09…634ae).
ACCEL_SHA256 = "5ad0ce09ce1f1763f4b2c16f2ec08da1abb6a0564b0cf715e9be4c0ac7a634ae"


def random_obs(rng: np.random.Generator, n: int) -> dict[str, np.ndarray]:
    objects = rng.choice(np.array([1, 2, 8], dtype=np.uint8), size=(n, 5, 5))  # empty, wall, goal
    image = np.stack([objects, np.zeros_like(objects), np.zeros_like(objects)], axis=-1)
    return {"image": image, "direction": rng.integers(0, 4, size=n)}


@pytest.fixture
def agent(random_dcd_checkpoint):
    return load_maze_agent(f"dcd:{random_dcd_checkpoint}")


def rollout(agent, seed: int, steps: int = 25, n: int = 8) -> np.ndarray:
    obs_rng, rng = np.random.default_rng(123), np.random.default_rng(seed)
    state, actions = agent.initial_state(n), []
    for _ in range(steps):
        a, state = agent.act(random_obs(obs_rng, n), state, rng)
        assert a.dtype == np.int64 and a.shape == (n,) and ((0 <= a) & (a < 7)).all()
        actions.append(a)
    return np.stack(actions)


def test_actions_are_reproducible_from_the_rng(agent, random_dcd_checkpoint):
    other = load_maze_agent(f"dcd:{random_dcd_checkpoint}")
    np.testing.assert_array_equal(rollout(agent, seed=7), rollout(other, seed=7))
    assert not np.array_equal(rollout(agent, seed=7), rollout(agent, seed=8)), "actions must be sampled, not argmax"


def test_rng_consumption_is_one_uniform_per_row(agent):
    rng, mirror = np.random.default_rng(3), np.random.default_rng(3)
    agent.act(random_obs(np.random.default_rng(0), 5), agent.initial_state(5), rng)
    mirror.random(5)
    assert rng.random() == mirror.random()


def test_sampling_matches_the_categorical():
    probs = np.array([0.1, 0.2, 0.7, 0.0, 0.0, 0.0, 0.0])
    logits = torch.log(torch.tensor(probs)).repeat(40_000, 1)
    freq = np.bincount(sample_from_logits(logits, np.random.default_rng(0)), minlength=7) / 40_000
    np.testing.assert_allclose(freq, probs, atol=0.01)
    assert freq[3:].sum() == 0


def test_lstm_cell_step_equals_the_checkpoints_lstm(agent):
    """The fast per-step LSTMCell must reproduce nn.LSTM (the module the weights belong to) over a sequence."""
    net, n, steps = agent.network, 6, 12
    obs_rng = np.random.default_rng(1)
    observations = [random_obs(obs_rng, n) for _ in range(steps)]
    state, stepped = agent.initial_state(n), []
    for obs in observations:
        logits, state = agent.logits(obs, state)
        stepped.append(logits)
    with torch.no_grad():
        inputs = []
        for obs in observations:
            image = torch.tensor(obs["image"], dtype=torch.float32).permute(0, 3, 1, 2) / 10.0
            onehot = torch.nn.functional.one_hot(torch.tensor(obs["direction"]), 4).float()
            inputs.append(torch.cat([net.image_conv(image), net.scalar_embed(onehot)], dim=1))
        hidden, _ = net.rnn.rnn(torch.stack(inputs))  # (steps, n, 256), zero initial state
        reference = net.actor(hidden)
    torch.testing.assert_close(torch.stack(stepped), reference, rtol=1e-5, atol=1e-5)


def test_rows_are_independent_without_the_quirk(agent):
    obs = random_obs(np.random.default_rng(2), 10)
    full, _ = agent.logits(obs, agent.initial_state(10))
    idx = np.array([1, 4, 7])
    part, _ = agent.logits({k: v[idx] for k, v in obs.items()}, agent.initial_state(3))
    torch.testing.assert_close(part, full[idx])


def test_select_state(agent):
    n, obs_rng, rng = 6, np.random.default_rng(4), np.random.default_rng(0)
    state = agent.initial_state(n)
    for _ in range(3):
        _, state = agent.act(random_obs(obs_rng, n), state, rng)
    idx = np.array([1, 3, 4])
    kept = agent.select_state(state, idx)
    for part, old in zip(kept, state):
        torch.testing.assert_close(part, old[idx])
    # Acting on the kept rows gives what those rows would have got in the full batch.
    obs = random_obs(obs_rng, n)
    full, _ = agent.logits(obs, state)
    sub, _ = agent.logits({k: v[idx] for k, v in obs.items()}, kept)
    torch.testing.assert_close(sub, full[idx])


def test_heading_onehot_correct_and_quirk(random_dcd_checkpoint):
    direction = np.array([0, 2, 2, 3, 1, 1, 1])
    plain = load_maze_agent(f"dcd:{random_dcd_checkpoint}")
    np.testing.assert_array_equal(plain.heading_onehot(direction), np.eye(4)[direction])

    whole = load_maze_agent(f"dcd:{random_dcd_checkpoint}?heading_quirk=1&quirk_group=0")
    np.testing.assert_array_equal(whole.heading_onehot(direction), np.ones((7, 4)))
    np.testing.assert_array_equal(whole.heading_onehot(np.array([2, 2])), [[0, 0, 1, 0]] * 2)

    grouped = load_maze_agent(f"dcd:{random_dcd_checkpoint}?heading_quirk=1&quirk_group=3")
    expected = [[1, 0, 1, 0]] * 3 + [[0, 1, 0, 1]] * 3 + [[0, 1, 0, 0]]  # groups {0,2,2}, {3,1,1}, {1}
    np.testing.assert_array_equal(grouped.heading_onehot(direction), expected)
    assert grouped.heading_onehot(np.zeros(0, np.int64)).shape == (0, 4)


def test_quirk_couples_rows_in_a_group(random_dcd_checkpoint):
    quirky = load_maze_agent(f"dcd:{random_dcd_checkpoint}?heading_quirk=1")  # default group of 10
    obs = random_obs(np.random.default_rng(5), 4)
    obs["direction"] = np.array([0, 0, 0, 0])
    changed = {"image": obs["image"], "direction": np.array([0, 0, 0, 3])}
    before, _ = quirky.logits(obs, quirky.initial_state(4))
    after, _ = quirky.logits(changed, quirky.initial_state(4))
    assert not torch.allclose(before[0], after[0]), "row 0 must see row 3's heading under the quirk"
    plain = load_maze_agent(f"dcd:{random_dcd_checkpoint}")
    torch.testing.assert_close(before, plain.logits(obs, plain.initial_state(4))[0])  # same heading: no difference
    torch.testing.assert_close(plain.logits(changed, plain.initial_state(4))[0][0], before[0])


def test_torchscript_export_of_the_dcd_network_acts_identically(agent, tmp_path):
    """Cross-checks the TorchScript calling convention against the DCD agent: same weights, same actions."""

    class Exported(torch.nn.Module):
        def __init__(self, net):
            super().__init__()
            self.net = net
            self.cell = torch.nn.LSTMCell(149, 256)
            self.cell.load_state_dict({k.replace("_l0", ""): v for k, v in net.rnn.rnn.state_dict().items()})
            self.state_size = 512

        def forward(self, image: torch.Tensor, direction: torch.Tensor, state: torch.Tensor):
            x = self.net.image_conv(image.permute(0, 3, 1, 2) / 10.0)
            s = self.net.scalar_embed(torch.nn.functional.one_hot(direction, 4).float())
            h, c = self.cell(torch.cat([x, s], dim=1), (state[:, :256], state[:, 256:]))
            return self.net.actor[1].linear(self.net.actor[0](h)), torch.cat([h, c], dim=1)

    path = tmp_path / "exported.pt"
    torch.jit.script(Exported(agent.network)).save(str(path))
    scripted = load_maze_agent(f"torchscript:{path}")
    assert scripted.state_size == 512
    np.testing.assert_array_equal(rollout(scripted, seed=11), rollout(agent, seed=11))


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
