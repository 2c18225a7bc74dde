"""Agents as data: the files a spec names become bytes, and a process that unpacks them loads the same agent."""

from __future__ import annotations

import shutil

import numpy as np
import pytest

from dsage_ray.agents import loader, shipping
from dsage_ray.agents.loader import ASSETS_DIR
from dsage_ray.domains.maze.agents import load_maze_agent


@pytest.fixture
def fresh_copies(monkeypatch):
    """Each test starts as a process that has installed nothing."""
    monkeypatch.setattr(loader, "LOCAL_COPIES", {})
    monkeypatch.setattr(shipping, "LOCAL_COPIES", loader.LOCAL_COPIES)
    return loader.LOCAL_COPIES


@pytest.mark.parametrize("spec, paths", [
    ("dcd:accel", []), ("rllib:ppo_maze", []), ("builtin:random", []), ("random", []), ("astar", []),
    ("dcd:/x/model.tar?heading_quirk=0", ["/x/model.tar"]), ("rllib:runs/ckpt?greedy=1", ["runs/ckpt"]),
    ("python:policies/p.py:act", ["policies/p.py"]), ("python:my_pkg.policies:act", []),
    ("sb3:m.zip", ["m.zip"]), ("torchscript:a.pt", ["a.pt"]),
])
def test_the_paths_a_spec_names(spec, paths):
    assert shipping.spec_paths(spec) == paths


def test_a_config_section_names_its_agent_and_reference():
    section = {"agent": "dcd:/a.tar", "reference": "rllib:/b", "episodes": 50, "measures": ["x"], "empty": ""}
    assert shipping.config_agent_specs(section) == ["dcd:/a.tar", "rllib:/b"]


@pytest.mark.parametrize("shipped, spec_of", [("accel", lambda p: f"dcd:{p / 'model_20000.tar'}"),
                                              ("ppo_maze", lambda p: f"rllib:{p}")])
def test_an_agent_loads_from_its_bytes_after_its_file_is_gone(tmp_path, fresh_copies, shipped, spec_of):
    copy = tmp_path / "mine"
    shutil.copytree(ASSETS_DIR / shipped, copy)
    spec = spec_of(copy)
    before = load_maze_agent(spec)
    files = shipping.pack_agent_files([spec, spec])  # named twice, packed once
    assert len(files) == 1 and files[0].target == spec.split(":", 1)[1]
    shutil.rmtree(copy)  # what a node without the driver's disk sees
    with pytest.raises(Exception, match="not found"):
        load_maze_agent(spec)
    shipping.install_agent_files(files)
    after = load_maze_agent(spec)
    assert after.spec == spec
    observation = maze_observations()
    np.testing.assert_array_equal(act(before, observation), act(after, observation))


def maze_observations():
    rng = np.random.default_rng(0)
    return {"image": rng.integers(0, 6, size=(4, 5, 5, 3)).astype(np.uint8), "direction": rng.integers(0, 4, size=4)}


def act(agent, observation):
    actions, _ = agent.act(observation, agent.initial_state(4), np.random.default_rng(1))
    return actions


def test_a_missing_path_is_left_to_the_loader_to_name(tmp_path, fresh_copies):
    assert shipping.pack_agent_files([f"dcd:{tmp_path / 'nope.tar'}"]) == ()
