"""Stable-Baselines3's and the RL Zoo's files are read as data: forged ones run nothing and are refused in one line."""

from __future__ import annotations

import base64
import json
import os
import pickle
import zipfile

import gymnasium as gym
import numpy as np
import pytest

from dsage_ray.agents.base import AgentError
from dsage_ray.agents.rl_zoo import read_run_folder, read_zoo_yaml
from dsage_ray.agents.sb3_files import read_save, read_vecnormalize, recorded_space
from dsage_ray.agents import load_agent
from tests.agents.conftest import shared_dir
from tests.agents.test_sb3 import make_run_folder

pytest.importorskip("stable_baselines3")
ZOO = shared_dir() / "models" / "rl_zoo"


class Touch:
    """Pickles as a call of ``os.system``: what a forged file would run under a plain unpickler."""

    def __init__(self, marker):
        self.marker = marker

    def __reduce__(self):
        return os.system, (f"touch {self.marker}",)


def test_a_forged_vecnormalize_runs_nothing(tmp_path):
    folder = make_run_folder(tmp_path)
    marker = tmp_path / "ran"
    (folder / "CartPole-v1" / "vecnormalize.pkl").write_bytes(pickle.dumps(Touch(marker)))
    env = gym.make("CartPole-v1")
    with pytest.raises(AgentError, match=r"does not read as data .*it names posix.system") as info:
        load_agent(f"sb3:{folder}", observation_space=env.observation_space, action_space=env.action_space, env=env)
    assert "\n" not in str(info.value)
    assert not marker.exists()


def test_a_forged_config_runs_nothing(tmp_path):
    folder = make_run_folder(tmp_path)
    marker = tmp_path / "ran"
    config = folder / "CartPole-v1" / "config.yml"
    config.write_text(f"!!python/object/apply:os.system\n- touch {marker}\n")
    with pytest.raises(AgentError, match="is not a zoo YAML file read as data .*nothing in it ran"):
        read_run_folder(folder, label="x")
    config.write_text(f"!!python/object/apply:collections.OrderedDict\n- - - normalize\n    - !!python/object/apply:"
                      f"os.system [touch {marker}]\n")
    with pytest.raises(AgentError, match="not a zoo YAML file read as data"):
        read_run_folder(folder, label="x")
    assert not marker.exists()


def forge_entry(zip_path, key: str, payload) -> None:
    with zipfile.ZipFile(zip_path) as archive:
        entries = {name: archive.read(name) for name in archive.namelist()}
    data = json.loads(entries["data"])
    data[key] = {":type:": "<class 'function'>",
                 ":serialized:": base64.b64encode(pickle.dumps(payload)).decode()}
    entries["data"] = json.dumps(data).encode()
    with zipfile.ZipFile(zip_path, "w") as archive:
        for name, blob in entries.items():
            archive.writestr(name, blob)


def test_a_forged_save_runs_nothing_whichever_entry_carries_it(tmp_path):
    folder = make_run_folder(tmp_path)
    model = folder / "CartPole-v1.zip"
    marker = tmp_path / "ran"
    forge_entry(model, "_last_obs", Touch(marker))  # training state: dropped, the policy still loads
    env = gym.make("CartPole-v1")
    agent = load_agent(f"sb3:{folder}", observation_space=env.observation_space, action_space=env.action_space,
                           env=env)
    assert agent.policy.model.policy is not None
    forge_entry(model, "policy_class", Touch(marker))  # what the policy needs: refused
    with pytest.raises(AgentError, match=r"its 'policy_class' does not read as data .*posix.system"):
        read_save(model, label="x")
    assert not marker.exists()


def test_the_zoo_yaml_tag_reads_as_a_plain_mapping(tmp_path):
    path = tmp_path / "config.yml"
    path.write_text("!!python/object/apply:collections.OrderedDict\n- - - normalize\n    - true\n  - - frame_stack\n"
                    "    - 4\n")
    assert read_zoo_yaml(path, label="x") == {"normalize": True, "frame_stack": 4}


@pytest.mark.skipif(not ZOO.is_dir(), reason=f"the RL Zoo agents are read from {ZOO} (not present)")
def test_the_zoos_sb3_1_saves_and_statistics_read_as_data():
    save = read_save(ZOO / "ppo" / "BipedalWalker-v3_1" / "BipedalWalker-v3.zip", label="x")
    assert save.sb3_version.startswith("1.")
    assert recorded_space(save.data["observation_space"]).shape == (24,)
    assert recorded_space(save.data["action_space"]) == gym.spaces.Box(-1, 1, (4,), np.float32)
    stats = read_vecnormalize(ZOO / "ppo" / "BipedalWalker-v3_1" / "BipedalWalker-v3" / "vecnormalize.pkl", label="x")
    assert stats.mean.shape == (24,) and stats.clip == 10.0 and np.all(stats.var > 0)
