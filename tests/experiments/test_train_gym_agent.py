"""``experiments/train_gym_agent.py`` (RLlib PPO) and ``experiments/train_sb3_agent.py`` (SB3 PPO) end to end:
one tiny training on CartPole-v1 each, in a subprocess run in a tmp folder (their ``tb_logs/`` lands there); the
RLlib script's audits during training (``--audit-every``) in the gym domain."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from tests.scripts import import_script

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


@pytest.mark.slow  # a whole training script with audits; the callback and the gym audit are covered by the default suite
def test_rllib_script_audits_each_iteration_in_the_shipped_space_of_its_env(tmp_path):
    done = run_script(GYM_SCRIPT, ["--run-name", "audited", "--total-env-steps", "257", "--train-batch-size", "256",
                                   "--minibatch-size", "128", "--num-epochs", "1", "--num-envs", "2",
                                   "--eval-episodes", "1", "--audit-every", "1", "--audit-budget", "20",
                                   "--audit-preset", "tiny", "--no-audit-background", "--audit-episodes", "2"],
                      tmp_path)
    run_dir = tmp_path / "tb_logs" / "audited"
    series = json.loads((run_dir / "audit_series" / "series.json").read_text())
    assert series["domain"] == "gym" and series["budget"] == 20 and series["episodes"] == 2
    assert series["overrides"]["gym.space"] == "cartpole" and series["overrides"]["gym.env"] == "CartPole-v1"
    audited = [r for r in series["records"] if r["error"] is None]
    assert audited, series["records"]
    assert {r["label"] for r in series["records"]} <= {"iter_1", "iter_2"}
    assert (run_dir / "checkpoints" / "iter_1").is_dir()
    assert "  audit of iteration 1: suite success" in done.stdout
    assert f"audit series: {run_dir.resolve() / 'audit_series'}" in done.stdout


@pytest.mark.parametrize("flags, message", [
    (["--env-id", "Acrobot-v1"], "error: --audit-space: no shipped space is for --env-id Acrobot-v1"),
    (["--audit-space", "nosuch"], "error: --audit-space nosuch: space 'nosuch': no such file"),
    (["--audit-budget", "10"], "--audit-budget 10): budget: must be at least n_rand=20"),
    (["--num-cpus", "1"], "background audits need a CPU of their own"),
])
def test_rllib_script_refuses_audits_it_cannot_run_before_anything_runs(flags, message, tmp_path, monkeypatch,
                                                                        capsys):
    script = import_script(GYM_SCRIPT, monkeypatch)
    monkeypatch.chdir(tmp_path)
    assert script.main(["--audit-every", "1", *flags]) == 2
    assert message in capsys.readouterr().err
    assert not (tmp_path / "tb_logs").exists()


def test_rllib_script_audits_its_env_id_with_its_env_config_as_fixed_keywords(monkeypatch):
    from dsage_ray.domains.gym.space import build_space, parse_env_arg, read_space_tables

    script = import_script(GYM_SCRIPT, monkeypatch)
    env_config = {"gravity": -8.0, "enable_wind": False, "render_mode": "rgb_array", "nested": {"a": [1, 2]}}
    args = script.parse_args(["--env-id", "LunarLander-v3", "--audit-every", "5"])
    overrides = script.audit_overrides(args, env_config)
    assert (overrides["gym.space"], overrides["gym.env"]) == ("lunarlander", "LunarLander-v3")
    assert dict(parse_env_arg(a) for a in overrides["gym.env_args"]) == env_config
    space = build_space(read_space_tables("lunarlander")[0], env_args=overrides["gym.env_args"])
    assert space.env_args["enable_wind"] is False  # over the space file's [env] args
    assert script.audit_overrides(script.parse_args([]), {}) == {"gym.space": "cartpole", "gym.env": "CartPole-v1",
                                                                 "gym.env_args": ()}


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
