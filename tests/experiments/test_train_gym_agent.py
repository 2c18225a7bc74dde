"""``experiments/train_gym_agent.py`` (RLlib PPO) and ``experiments/train_sb3_agent.py`` (SB3 PPO) end to end:
one tiny training on CartPole-v1 each, in a subprocess run in a tmp folder (their ``tb_logs/`` lands there)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

REPO_ROOT = Path(__file__).resolve().parents[2]
GYM_SCRIPT = REPO_ROOT / "experiments" / "train_gym_agent.py"
SB3_SCRIPT = REPO_ROOT / "experiments" / "train_sb3_agent.py"


def run_script(script: Path, args: list[str], cwd: Path) -> subprocess.CompletedProcess:
    env = dict(os.environ, PYTHONPATH=str(REPO_ROOT), RAY_AUTH_MODE="disabled")
    done = subprocess.run([sys.executable, str(script), *args], cwd=cwd, env=env, capture_output=True, text=True,
                          timeout=240)
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-4000:]
    return done


def test_rllib_script_trains_one_iteration_and_exports_a_loadable_module(tmp_path):
    import gymnasium as gym
    from ray.rllib.core.rl_module.rl_module import RLModule

    export = tmp_path / "exported"
    done = run_script(GYM_SCRIPT, ["--run-name", "tiny", "--total-env-steps", "1", "--train-batch-size", "256",
                                   "--minibatch-size", "128", "--num-epochs", "1", "--num-envs", "2",
                                   "--eval-episodes", "2", "--export", str(export)], tmp_path)
    assert "greedy evaluation on CartPole-v1" in done.stdout
    assert f"tensorboard --logdir {tmp_path.resolve() / 'tb_logs' / 'tiny'}" in done.stdout
    assert {p.name for p in export.iterdir()} >= {"class_and_ctor_args.pkl", "module_state.pkl", "metadata.json"}
    run_dir = tmp_path / "tb_logs" / "tiny"
    assert list(run_dir.glob("events.out.tfevents.*"))
    evaluation = json.loads((run_dir / "evaluation.json").read_text())
    assert evaluation["episodes"] == 2 and evaluation["seeds"] == [1000, 1001]
    assert json.loads((run_dir / "progress.json").read_text())["iteration"] == 1

    module = RLModule.from_checkpoint(str(export))
    env = gym.make("CartPole-v1")
    assert module.observation_space == env.observation_space
    assert module.action_space == env.action_space


def test_sb3_script_trains_a_few_hundred_steps_and_saves_a_loadable_model(tmp_path):
    from stable_baselines3 import PPO

    done = run_script(SB3_SCRIPT, ["--run-name", "tiny", "--total-env-steps", "256", "--n-steps", "64",
                                   "--num-envs", "2", "--n-epochs", "1", "--eval-episodes", "2"], tmp_path)
    model_path = tmp_path / "tb_logs" / "tiny" / "model.zip"
    assert "greedy evaluation on CartPole-v1" in done.stdout
    assert str(model_path.resolve()) in done.stdout
    model = PPO.load(model_path, device="cpu")
    assert model.num_timesteps >= 256
    assert json.loads((tmp_path / "tb_logs" / "tiny" / "evaluation.json").read_text())["episodes"] == 2


@pytest.mark.parametrize("script", [GYM_SCRIPT, SB3_SCRIPT], ids=lambda s: s.name)
def test_a_bad_env_config_is_rejected_before_anything_runs(script, tmp_path):
    env = dict(os.environ, PYTHONPATH=str(REPO_ROOT))
    done = subprocess.run([sys.executable, str(script), "--env-config", "[1, 2]"], cwd=tmp_path, env=env,
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 2
    assert "--env-config" in done.stderr
    assert not (tmp_path / "tb_logs").exists()
