"""Train an agent for any Gymnasium environment with Stable-Baselines3's PPO (CleanRL-style: one file).

The environment is ``gymnasium.make(--env-id, **--env-config)``, vectorised ``--num-envs`` times in one process
(SB3's ``DummyVecEnv``); the policy is SB3's ``MlpPolicy`` (separate 64-64 tanh MLPs for the policy and the
value function by default). SB3 logs its own metrics (``rollout/ep_rew_mean``, losses, fps) to TensorBoard
under ``tb_logs/<run_name>/``; the trained model is saved as ``tb_logs/<run_name>/model.zip``. At the end the
model is evaluated greedily (``deterministic=True``) for ``--eval-episodes`` episodes of the *default* env
(``gymnasium.make(--env-id)``, seeds ``--eval-seed`` onwards) and the mean return is printed.

Usage (``--help`` lists every flag of :class:`Args` with its description and default)::

    nice -n 10 python experiments/train_sb3_agent.py --run-name sb3_cartpole               # CartPole-v1, 50k steps
    tensorboard --logdir tb_logs/sb3_cartpole

    # LunarLander-v3 (rl-baselines3-zoo's settings): ~1M steps
    nice -n 10 python experiments/train_sb3_agent.py --env-id LunarLander-v3 --run-name sb3_lunarlander \\
        --total-env-steps 1000000 --num-envs 16 --n-steps 1024 --batch-size 64 --n-epochs 4 \\
        --gamma 0.999 --gae-lambda 0.98 --entropy-coeff 0.01

``model.zip`` is a Stable-Baselines3 save (``PPO.load``); like any pickle-based checkpoint, loading it can run
code, so only load models you trust.
"""

from __future__ import annotations

import dataclasses
import json
import sys
import time
from pathlib import Path

import tyro

from dsage_ray.integrations.training import check_env_flags, greedy_returns, report_evaluation


@dataclasses.dataclass
class Args:
    """The script's flags: ``--help`` prints each with the description under it."""

    env_id: str = "CartPole-v1"
    """Gymnasium env id"""
    env_config: str = "{}"
    """JSON object of keyword arguments for gymnasium.make in training, e.g. '{"gravity": -8.0}'"""
    run_name: str = "sb3_ppo"
    """folder under tb_logs/ that holds the run"""
    seed: int = 0
    """SB3's seed (envs, policy initialisation)"""
    total_env_steps: int = 50_000
    """environment steps of training"""
    max_minutes: float = 0.0
    """also stop after this much wall-clock training time (0 = no limit)"""
    num_envs: int = 8
    """vectorised envs (DummyVecEnv, one process)"""

    # PPO (SB3's names)
    lr: float = 3e-4
    """Adam learning rate"""
    n_steps: int = 256
    """env steps per env per rollout (the batch is n_steps * num_envs)"""
    batch_size: int = 64
    """SGD minibatch size"""
    n_epochs: int = 10
    """passes over each rollout"""
    gamma: float = 0.99
    """discount factor"""
    gae_lambda: float = 0.95
    """GAE lambda"""
    entropy_coeff: float = 0.0
    """entropy bonus coefficient"""
    clip_range: float = 0.2
    """PPO clip range"""

    # Evaluation and machine
    eval_episodes: int = 20
    """greedy episodes of the final evaluation on the default env"""
    eval_seed: int = 1000
    """seed of the first evaluation episode (then +1 per episode)"""
    torch_threads: int = 1
    """torch threads (the machine is shared)"""


def parse_args(argv: list[str] | None = None) -> Args:
    """``Args`` from the command line (``--help`` lists every flag)."""
    return tyro.cli(Args, args=argv, description=__doc__.split("\n\n")[0])


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    from dsage_ray.errors import InputError

    try:
        env_config = check_env_flags(args)
    except InputError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.callbacks import BaseCallback
    from stable_baselines3.common.env_util import make_vec_env

    torch.set_num_threads(args.torch_threads)
    run_dir = Path("tb_logs") / args.run_name
    run_dir.mkdir(parents=True, exist_ok=True)
    (run_dir / "args.json").write_text(json.dumps(dataclasses.asdict(args), indent=2))

    class TimeLimit(BaseCallback):
        """Stops training after --max-minutes (checked after every env step of the vectorised env)."""

        def _on_step(self) -> bool:
            return args.max_minutes <= 0 or time.perf_counter() - started < 60 * args.max_minutes

    env = make_vec_env(args.env_id, n_envs=args.num_envs, seed=args.seed, env_kwargs=env_config)
    model = PPO("MlpPolicy", env, learning_rate=args.lr, n_steps=args.n_steps, batch_size=args.batch_size,
                n_epochs=args.n_epochs, gamma=args.gamma, gae_lambda=args.gae_lambda, ent_coef=args.entropy_coeff,
                clip_range=args.clip_range, seed=args.seed, device="cpu", tensorboard_log=str(run_dir), verbose=0)
    started = time.perf_counter()
    model.learn(total_timesteps=args.total_env_steps, callback=TimeLimit(), tb_log_name="ppo", progress_bar=False)
    wall_s = time.perf_counter() - started
    env.close()
    model_path = run_dir / "model.zip"
    model.save(model_path)

    loaded = PPO.load(model_path, device="cpu")  # evaluated as a user would read it back
    returns = greedy_returns(lambda obs, _space: loaded.predict(obs, deterministic=True)[0], args.env_id,
                             args.eval_episodes, args.eval_seed)
    print(f"done: {model.num_timesteps} env steps in {wall_s / 60:.1f} min")
    report_evaluation(run_dir, args.env_id, returns, args.eval_seed, env_steps=int(model.num_timesteps), wall_s=wall_s)
    print(f"model: {model_path.resolve()}")
    print(f"args, evaluation: {(run_dir / 'args.json').resolve()}, {(run_dir / 'evaluation.json').resolve()}")
    print(f"open it in TensorBoard: tensorboard --logdir {run_dir.resolve()}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
