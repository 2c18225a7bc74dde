"""``rllib:PATH``: checkpoints trained here by the training script, and broken ones that must fail clearly.

The trained checkpoint comes from ``experiments/train_maze_agent.py`` itself (two tiny PPO iterations, then a
resumed third), run in a subprocess so its Ray instance never meets the test process's.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import textwrap

import gymnasium as gym
import numpy as np
import pytest
import torch

from dsage_ray.agents import AgentError
from dsage_ray.domains.maze.agents import load_maze_agent
from dsage_ray.domains.maze.generator import random_valid_levels
from dsage_ray.agents.loader import ASSETS_DIR
from dsage_ray.agents.rllib import MODULES_SUBDIR, RLlibAgent
from dsage_ray.agents.rllib_module import MAZE_ACTION_SPACE, MAZE_OBSERVATION_SPACE, MazeRLModule
from dsage_ray.domains.maze import evaluate

from tests.agents.conftest import REPO_ROOT

sys.path.insert(0, str(REPO_ROOT / "experiments"))  # the training env lives beside the training script

from maze_training_env import RandomMazeEnv  # noqa: E402

TINY_TRAINING = ["--train-batch-size", "200", "--minibatch-size", "64", "--num-epochs", "1", "--num-envs", "2",
                 "--checkpoint-every", "1", "--eval-every", "0", "--hidden", "32", "--no-see-through-walls"]


def load_error(spec: str) -> str:
    with pytest.raises(AgentError) as info:
        load_maze_agent(spec)
    message = str(info.value)
    assert "\n" not in message
    return message


def train(workdir, *extra: str) -> subprocess.CompletedProcess:
    env = dict(os.environ, RAY_AUTH_MODE="disabled", PYTHONPATH=str(REPO_ROOT))
    return subprocess.run([sys.executable, str(REPO_ROOT / "experiments" / "train_maze_agent.py"), "--run-name", "t",
                           *TINY_TRAINING, *extra], cwd=workdir, env=env, capture_output=True, text=True, timeout=300)


@pytest.fixture(scope="module")
def trained(tmp_path_factory):
    """An algorithm checkpoint after 2 PPO iterations + 1 resumed iteration, and the exported module."""
    workdir = tmp_path_factory.mktemp("train")
    first = train(workdir, "--total-env-steps", "400")
    assert first.returncode == 0, first.stderr[-3000:]
    second = train(workdir, "--total-env-steps", "600", "--resume", "--export", str(workdir / "exported"))
    assert second.returncode == 0, second.stderr[-3000:]
    return {"run": workdir / "tb_logs" / "t", "checkpoint": workdir / "tb_logs" / "t" / "checkpoint",
            "exported": workdir / "exported", "log": first.stdout + second.stdout, "err": first.stderr + second.stderr}


def make_module(**model_config) -> MazeRLModule:
    torch.manual_seed(0)
    return MazeRLModule(observation_space=MAZE_OBSERVATION_SPACE, action_space=MAZE_ACTION_SPACE,
                        model_config={"hidden": 16, **model_config})


# --- trained by the script ------------------------------------------------------------------------------------


def test_training_script_checkpoints_resumes_and_logs(trained):
    progress = json.loads((trained["run"] / "progress.json").read_text())
    assert progress["iteration"] == 3 and progress["env_steps"] >= 600
    assert "resumed at iteration 2" in trained["log"]
    assert json.loads((trained["run"] / "args.json").read_text())["see_through_walls"] is False  # --no-… works
    assert list(trained["run"].glob("events.out.tfevents.*")), "no TensorBoard file"
    assert (trained["exported"] / "module_state.pkl").is_file()
    assert "RLModuleConfig" not in trained["err"], "RLlib's constructor deprecation warning is back"


@pytest.mark.parametrize("which", ["checkpoint", "module_dir", "exported"])
def test_trained_checkpoint_loads_without_ray_and_plays(trained, which, monkeypatch):
    import ray

    def no_ray(*args, **kwargs):
        raise AssertionError("loading a module must not start Ray")

    # Another test file of this pytest worker may have started the session's cluster already: a start attempt fails.
    monkeypatch.setattr(ray, "init", no_ray)
    was_up = ray.is_initialized()
    path = {"checkpoint": trained["checkpoint"], "exported": trained["exported"],
            "module_dir": trained["checkpoint"] / MODULES_SUBDIR / "default_policy"}[which]
    agent = load_maze_agent(f"rllib:{path}")
    assert isinstance(agent, RLlibAgent) and not agent.recurrent
    assert ray.is_initialized() == was_up, "loading a module must not start Ray"
    level = random_valid_levels(1, seed=3)[0]
    first = evaluate(level, agent, episodes=4, seed=11)
    again = evaluate(level, agent, episodes=4, seed=11)
    assert first.episodes == 4 and 0 < first.mean_path_length <= first.max_steps
    np.testing.assert_array_equal(first.episode_lengths, again.episode_lengths)


def test_loaded_module_matches_the_trained_weights(trained):
    """Same logits as RLlib's own from_checkpoint on the algorithm checkpoint's module."""
    from ray.rllib.core.columns import Columns
    from ray.rllib.core.rl_module import RLModule

    module = RLModule.from_checkpoint((trained["checkpoint"] / MODULES_SUBDIR / "default_policy").resolve())
    agent = load_maze_agent(f"rllib:{trained['exported']}")
    env = RandomMazeEnv()
    obs, _ = env.reset(seed=0)
    batch = {"image": obs["image"][None], "direction": np.array([obs["direction"]])}
    ours, _ = agent.logits(batch, agent.initial_state(1))
    theirs = module.forward_inference({Columns.OBS: {k: torch.as_tensor(v) for k, v in batch.items()}})
    torch.testing.assert_close(ours, theirs[Columns.ACTION_DIST_INPUTS].detach())


# --- recurrent modules ------------------------------------------------------------------------------------------


def test_recurrent_module_steps_like_the_whole_sequence(tmp_path):
    """Stepping with our carried state equals one RLlib-style (B, T) forward pass over the episode."""
    from ray.rllib.core.columns import Columns

    module = make_module(use_lstm=True, max_seq_len=8)
    module.save_to_path(str(tmp_path / "lstm"))
    agent = load_maze_agent(f"rllib:{tmp_path / 'lstm'}")
    assert agent.recurrent
    rng = np.random.default_rng(0)
    steps, n = 6, 3
    images = rng.integers(0, 3, size=(n, steps, 5, 5, 3)).astype(np.uint8)
    directions = rng.integers(0, 4, size=(n, steps))
    state, stepped = agent.initial_state(n), []
    for t in range(steps):
        logits, state = agent.logits({"image": images[:, t], "direction": directions[:, t]}, state)
        stepped.append(logits)
    initial = {k: torch.as_tensor(v)[None].repeat(n, 1) for k, v in module.get_initial_state().items()}
    whole = module.forward_inference({Columns.OBS: {"image": torch.as_tensor(images),
                                                    "direction": torch.as_tensor(directions)},
                                      Columns.STATE_IN: initial})[Columns.ACTION_DIST_INPUTS]
    torch.testing.assert_close(torch.stack(stepped, dim=1), whole.detach())


def test_recurrent_agent_evaluates_with_shrinking_batches(tmp_path):
    make_module(use_lstm=True, max_seq_len=8).save_to_path(str(tmp_path / "lstm"))
    agent = load_maze_agent(f"rllib:{tmp_path / 'lstm'}")
    result = evaluate(random_valid_levels(1, seed=5)[0], agent, episodes=5, seed=2)
    assert result.episodes == 5  # episodes finishing at different times exercise select_state on the dict state


# --- options and bad checkpoints -------------------------------------------------------------------------------


def test_greedy_option_and_unknown_policy(trained):
    agent = load_maze_agent(f"rllib:{trained['checkpoint']}?greedy=1")
    assert agent.greedy
    assert "no module 'nope'" in load_error(f"rllib:{trained['checkpoint']}?policy=nope")


def test_not_a_checkpoint(tmp_path):
    (tmp_path / "random.txt").write_text("hello")
    assert "not an RLlib checkpoint" in load_error(f"rllib:{tmp_path}")
    assert "not found" in load_error(f"rllib:{tmp_path / 'missing'}")
    assert "not a folder" in load_error(f"rllib:{tmp_path / 'random.txt'}")


def test_corrupt_module_state(tmp_path, trained):
    broken = tmp_path / "broken"
    shutil.copytree(trained["exported"], broken)
    (broken / "module_state.pkl").write_bytes(b"\x80\x04garbage")
    assert "cannot load the module" in load_error(f"rllib:{broken}")
    (broken / "class_and_ctor_args.pkl").write_bytes(b"not a pickle")
    assert "unreadable class_and_ctor_args.pkl" in load_error(f"rllib:{broken}")


def test_mismatched_observation_space(tmp_path):
    other = MazeRLModule(observation_space=gym.spaces.Dict({
        "direction": gym.spaces.Discrete(4), "image": gym.spaces.Box(0, 255, (7, 7, 3), np.uint8)}),
        action_space=MAZE_ACTION_SPACE, model_config={"hidden": 8})
    other.save_to_path(str(tmp_path / "seven"))
    assert "does not match the maze observation" in load_error(f"rllib:{tmp_path / 'seven'}")


def test_module_class_that_cannot_be_imported(tmp_path, monkeypatch):
    source = tmp_path / "src"
    source.mkdir()
    (source / "vanishing_rlm.py").write_text(textwrap.dedent("""
        from dsage_ray.agents.rllib_module import MazeRLModule

        class VanishingModule(MazeRLModule):
            pass
    """))
    monkeypatch.syspath_prepend(str(source))
    import vanishing_rlm

    vanishing_rlm.VanishingModule(observation_space=MAZE_OBSERVATION_SPACE, action_space=MAZE_ACTION_SPACE,
                                  model_config={"hidden": 8}).save_to_path(str(tmp_path / "ckpt"))
    monkeypatch.delitem(sys.modules, "vanishing_rlm")
    shutil.rmtree(source)
    message = load_error(f"rllib:{tmp_path / 'ckpt'}")
    assert "vanishing_rlm.VanishingModule cannot be imported" in message


def test_shipped_agent_loads_without_deprecation_warnings():
    """``rllib:ppo_maze`` in a fresh process (RLlib warns once per process): nothing on stderr about deprecation."""
    if not (ASSETS_DIR / "ppo_maze").is_dir():
        pytest.skip("no shipped agent in this checkout")
    code = "from dsage_ray.domains.maze.agents import load_maze_agent; print(type(load_maze_agent('rllib:ppo_maze').module).__name__)"
    env = dict(os.environ, RAY_AUTH_MODE="disabled", PYTHONPATH=str(REPO_ROOT))
    done = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0 and done.stdout.strip() == "MazeRLModule", done.stderr[-2000:]
    assert "DeprecationWarning" not in done.stderr, done.stderr[-2000:]


def test_shipped_agent_loads_by_name():
    if not (ASSETS_DIR / "ppo_maze").is_dir():
        pytest.skip("no shipped agent in this checkout")
    agent = load_maze_agent("rllib:ppo_maze")
    assert isinstance(agent, RLlibAgent)
    assert "shipped agents: ppo_cartpole, ppo_lunarlander, ppo_maze" in load_error("rllib:not_shipped")
