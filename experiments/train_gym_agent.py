"""Train an agent for any Gymnasium environment with PPO on RLlib's new API stack (CleanRL-style: one file).

The environment is ``gymnasium.make(--env-id, **--env-config)``: RLlib builds it from the id itself, so any
registered Gymnasium env with a Box observation space and a Discrete (or Box) action space works. The policy
is RLlib's default PPO RLModule (``DefaultPPOTorchRLModule``: an MLP encoder of ``--fcnet-hiddens`` with tanh,
a linear policy head and a linear value head), so the exported checkpoint's class is RLlib's own and loads
with ``RLModule.from_checkpoint`` (and the ``rllib:`` loader of the ``gym`` domain) without project code.

The mean training episode return, episode length, PPO losses and throughput go to TensorBoard under
``tb_logs/<run_name>/`` each iteration. At the end the module is evaluated greedily (argmax of the logits of
``forward_inference``) for ``--eval-episodes`` episodes of the *default* env (``gymnasium.make(--env-id)``,
seeds ``--eval-seed`` onwards) and the mean return is printed.

Usage (``--help`` lists every flag of :class:`Args` with its description and default; a boolean flag ``--x``
is switched off with ``--no-x``)::

    # CartPole-v1 (the defaults): ~100-200k env steps, under a minute on 2 shared cores (140k steps, 32 s)
    nice -n 10 python experiments/train_gym_agent.py --run-name ppo_cartpole --total-env-steps 300000 \\
        --stop-return 475 --export dsage_ray/assets/agents/ppo_cartpole
    tensorboard --logdir tb_logs/ppo_cartpole

    # LunarLander-v3 (discrete; settings close to rl-baselines3-zoo's): 1.5M env steps in ~5 minutes, greedy ~220
    nice -n 10 python experiments/train_gym_agent.py --env-id LunarLander-v3 --run-name ppo_lunarlander \\
        --total-env-steps 1500000 --max-minutes 38 --num-envs 16 --train-batch-size 8192 --minibatch-size 128 \\
        --num-epochs 4 --gamma 0.999 --gae-lambda 0.98 --lr 3e-4 --entropy-coeff 0.01 \\
        --stop-return 250 --export dsage_ray/assets/agents/ppo_lunarlander

    # an env parameter changed for training (keyword arguments of gymnasium.make)
    nice -n 10 python experiments/train_gym_agent.py --env-id LunarLander-v3 --env-config '{"gravity": -8.0}'

Audits while training (``--audit-every N``, ``dsage_ray.integrations.rllib.AuditCallback`` in the ``gym`` domain):
every N iterations the current module is saved to ``tb_logs/<run_name>/checkpoints/iter_<N>`` and audited on a
parameter space of the env (``--audit-space``: a shipped space's name or a space file; by default the shipped space
of ``--env-id``, ``cartpole`` for CartPole-v1 and ``lunarlander`` for LunarLander-v3, and required for any other
env): the regression suite of earlier audits' failures re-evaluated, then a short warm-started DSAGE search of
``--audit-budget`` evaluations whose new failures join the suite. The audited env is ``--env-id`` with
``--env-config`` as fixed ``gym.make`` keywords and the space's parameters varied over them. The series lives in
``tb_logs/<run_name>/audit_series`` and its numbers go to the run's TensorBoard under ``audit/...`` with step =
env steps. The audits run in a Ray actor with a CPU of its own while training goes on (one at a time: one that
falls due while another runs is skipped with a warning; the end of training waits for the last);
``--no-audit-background`` audits between iterations instead. A failed audit logs one warning line; training goes
on::

    nice -n 10 python experiments/train_gym_agent.py --run-name ppo_cartpole_audited --total-env-steps 200000 \\
        --audit-every 10 --audit-budget 30
    nice -n 10 python experiments/train_gym_agent.py --env-id Acrobot-v1 --audit-every 10 --audit-space acrobot.toml

The run folder holds ``checkpoint/`` (the latest full algorithm checkpoint; also loadable as
``rllib:tb_logs/<run>/checkpoint``), ``args.json``, ``progress.json`` and TensorBoard event files.
``--export DIR`` copies the module-only checkpoint (``class_and_ctor_args.pkl``, ``module_state.pkl``,
``metadata.json``; a few hundred KB) there, e.g. into the package assets. An RLlib checkpoint is a pickle:
loading one runs code, so only load checkpoints you trust.
"""

from __future__ import annotations

import dataclasses
import json
import sys
import time
from pathlib import Path

import tyro

from dsage_ray.integrations import DEFAULT_AUDIT_BUDGET, DEFAULT_PRESET
from dsage_ray.integrations.training import (audit_callback, check_audit_flags, check_env_flags, export_module,
                                             finish_audits_and_report, greedy_returns, module_dir, print_audit,
                                             record_iteration, report_evaluation, save_checkpoint, write_scalars)


@dataclasses.dataclass
class Args:
    """The script's flags: ``--help`` prints each with the description under it."""

    env_id: str = "CartPole-v1"
    """Gymnasium env id (RLlib calls gymnasium.make on it)"""
    env_config: str = "{}"
    """JSON object of keyword arguments for gymnasium.make in training, e.g. '{"gravity": -8.0}'"""
    run_name: str = "ppo_gym"
    """folder under tb_logs/ that holds the run"""
    seed: int = 0
    """RLlib's seed (env runners, module initialisation)"""
    total_env_steps: int = 300_000
    """stop after this many environment steps"""
    max_minutes: float = 0.0
    """also stop after this much wall-clock training time (0 = no limit)"""
    stop_return: float = 0.0
    """also stop once the mean training episode return is >= this for --stop-patience iterations in a row
    (0 = never)"""
    stop_patience: int = 3
    """consecutive iterations at or above --stop-return that end training"""
    export: str = ""
    """at the end, copy the module-only checkpoint to this folder (empty = no export)"""

    # Sampling
    num_envs: int = 8
    """vectorised envs in the (single, local) env runner"""

    # PPO
    lr: float = 3e-4
    """Adam learning rate"""
    gamma: float = 0.99
    """discount factor"""
    gae_lambda: float = 0.95
    """GAE lambda"""
    train_batch_size: int = 4000
    """env steps per PPO iteration (train_batch_size_per_learner)"""
    minibatch_size: int = 256
    """SGD minibatch size"""
    num_epochs: int = 10
    """passes over each iteration's batch"""
    entropy_coeff: float = 0.0
    """entropy bonus coefficient"""
    vf_loss_coeff: float = 0.5
    """value-function loss coefficient"""
    vf_clip_param: float = 10_000.0
    """clip of the value-function loss (RLlib's default of 10 suits returns of order 1; large returns need more)"""
    clip_param: float = 0.2
    """PPO clip range"""
    kl_coeff: float = 0.0
    """initial coefficient of RLlib's adaptive KL penalty (0 = no KL loss, as in CleanRL and SB3)"""
    grad_clip: float = 0.5
    """global gradient-norm clip (0 = none)"""

    # Module (RLlib's DefaultModelConfig)
    fcnet_hiddens: tuple[int, ...] = (64, 64)
    """hidden layer sizes of the MLP encoder"""
    fcnet_activation: str = "tanh"
    """activation of the MLP encoder"""
    vf_share_layers: bool = False
    """one encoder for policy and value function (--no-vf-share-layers: a separate value encoder)"""

    # Bookkeeping and evaluation
    checkpoint_every: int = 10
    """iterations between algorithm checkpoints"""
    eval_episodes: int = 20
    """greedy episodes of the final evaluation on the default env"""
    eval_seed: int = 1000
    """seed of the first evaluation episode (then +1 per episode)"""
    num_cpus: int = 2
    """logical CPUs of the local Ray instance"""
    torch_threads: int = 1
    """torch threads for the learner (the machine is shared)"""

    # Audits while training (dsage_ray.integrations.rllib.AuditCallback, in the gym domain)
    audit_every: int = 0
    """training iterations between audits of the current policy (0 = no audits)"""
    audit_space: str = ""
    """the audits' parameter space (gym.space): a shipped space's name or a space file (TOML); empty = the shipped
    space of --env-id (CartPole-v1: cartpole, LunarLander-v3: lunarlander), required with --audit-every for
    other envs"""
    audit_budget: int = DEFAULT_AUDIT_BUDGET
    """real evaluations of each audit's DSAGE search (at least 20: its first 20 are random levels)"""
    audit_preset: str = DEFAULT_PRESET
    """the audits' preset (their search settings; --audit-budget replaces its budget)"""
    audit_episodes: int = 0
    """episodes per level in the audits' evaluations (0 = the preset's gym.episodes: tiny 2)"""
    audit_background: bool = True
    """audit in a Ray actor with a CPU of its own while training goes on (--no-audit-background: in the training
    process, between iterations)"""


def parse_args(argv: list[str] | None = None) -> Args:
    """``Args`` from the command line (``--help`` lists every flag; a boolean ``--x`` has ``--no-x``)."""
    return tyro.cli(Args, args=argv, description=__doc__.split("\n\n")[0])


def build_config(args: Args, env_config: dict):
    """The PPOConfig: the Gymnasium env by id, RLlib's default PPO module, one local env runner and learner."""
    from ray.rllib.algorithms.ppo import PPOConfig
    from ray.rllib.core.rl_module.default_model_config import DefaultModelConfig

    return (
        PPOConfig()
        .environment(args.env_id, env_config=env_config)
        # Sampling in the driver process: on 2 shared cores a remote env runner only adds copies.
        .env_runners(num_env_runners=0, num_envs_per_env_runner=args.num_envs)
        .learners(num_learners=0)
        .rl_module(model_config=DefaultModelConfig(fcnet_hiddens=list(args.fcnet_hiddens),
                                                   fcnet_activation=args.fcnet_activation,
                                                   vf_share_layers=args.vf_share_layers))
        .training(
            lr=args.lr,
            gamma=args.gamma,
            lambda_=args.gae_lambda,
            train_batch_size_per_learner=args.train_batch_size,
            minibatch_size=args.minibatch_size,
            num_epochs=args.num_epochs,
            entropy_coeff=args.entropy_coeff,
            vf_loss_coeff=args.vf_loss_coeff,
            vf_clip_param=args.vf_clip_param,
            clip_param=args.clip_param,
            use_kl_loss=args.kl_coeff > 0,
            kl_coeff=args.kl_coeff,
            grad_clip=args.grad_clip or None,
        )
        .debugging(seed=args.seed)
    )


def shipped_space_of(env_id: str) -> str | None:
    """The name of the gym domain's shipped space whose ``[env] id`` is ``env_id`` (``CartPole-v1``: ``cartpole``)."""
    from dsage_ray.domains.gym.space import read_space_tables, shipped_spaces

    return next((name for name in shipped_spaces() if read_space_tables(name)[0].get("env", {}).get("id") == env_id),
                None)


def toml_value(value) -> str:
    """``value`` (a JSON value of --env-config) as TOML, the form of a ``gym.env_args`` entry's value."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{json.dumps(str(k))} = {toml_value(v)}" for k, v in value.items()) + "}"
    if isinstance(value, list):
        return "[" + ", ".join(toml_value(v) for v in value) + "]"
    return json.dumps(value)


def audit_overrides(args: Args, env_config: dict) -> dict:
    """The gym domain's config keys of the audits: the space (``--audit-space``, else the shipped one of ``--env-id``),
    the env id, and the training's ``--env-config`` as fixed ``gym.make`` keywords (the space's parameters go over
    them). InputError, naming the flag, when there is no space or it does not load."""
    from dsage_ray.domains.gym.space import build_space, read_space_tables, shipped_spaces
    from dsage_ray.errors import InputError

    space = args.audit_space or shipped_space_of(args.env_id)
    if space is None:
        shipped = ", ".join(f"{name} ({read_space_tables(name)[0].get('env', {}).get('id')})"
                            for name in shipped_spaces())
        raise InputError(f"--audit-space: no shipped space is for --env-id {args.env_id} (shipped: {shipped}); give "
                         f"--audit-space NAME or a space file (TOML) to audit with --audit-every")
    env_args = tuple(f"{key}={toml_value(value)}" for key, value in env_config.items())
    try:
        build_space(read_space_tables(space)[0], env_id=args.env_id, env_args=env_args, source=space)
    except InputError as exc:  # SpaceError
        raise InputError(f"--audit-space {space}: {exc}") from None
    return {"gym.space": space, "gym.env": args.env_id, "gym.env_args": env_args}


def greedy_action(module):
    """``act(observation, action_space)`` of :func:`~dsage_ray.integrations.training.greedy_returns` for an
    RLModule: the argmax of its action logits (Discrete), or its Gaussian's mean clipped to the space (Box)."""
    import gymnasium as gym
    import numpy as np
    import torch
    from ray.rllib.core.columns import Columns

    def act(obs, action_space):
        with torch.no_grad():
            out = module.forward_inference({Columns.OBS: torch.as_tensor(np.asarray(obs, np.float32))[None]})
        logits = out[Columns.ACTION_DIST_INPUTS][0]
        if isinstance(action_space, gym.spaces.Discrete):
            return int(torch.argmax(logits))
        # Box: a diagonal Gaussian's inputs are [mean, log_std]; greedy = the mean, clipped
        mean = logits[: logits.shape[-1] // 2].numpy()
        return np.clip(mean, action_space.low, action_space.high)

    return act


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    from dsage_ray.errors import InputError

    try:
        env_config = check_env_flags(args)
        overrides = audit_overrides(args, env_config) if args.audit_every else {}
        check_audit_flags(args, domain="gym", overrides=overrides)
    except InputError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    import ray
    import torch
    from ray.rllib.core.rl_module.rl_module import RLModule
    from tensorboardX import SummaryWriter

    from dsage_ray.ray.session import start_ray

    torch.set_num_threads(args.torch_threads)
    run_dir = (Path("tb_logs") / args.run_name).resolve()  # RLlib reads paths as URIs: they must be absolute
    if (run_dir / "checkpoint").exists():
        print(f"{run_dir} already holds a run; pick another --run-name", file=sys.stderr)
        return 2
    run_dir.mkdir(parents=True, exist_ok=True)
    (run_dir / "args.json").write_text(json.dumps(dataclasses.asdict(args), indent=2))

    start_ray(num_cpus=args.num_cpus, log_to_driver=False)
    writer = SummaryWriter(str(run_dir))
    config = build_config(args, env_config)
    if args.audit_every:
        config.callbacks(audit_callback(args, run_dir, writer, domain="gym", overrides=overrides))
        print(f"auditing every {args.audit_every} iterations in the gym space {overrides['gym.space']}", flush=True)
    algo = config.build_algo()
    progress = {"iteration": 0, "env_steps": 0, "wall_s": 0.0, "episode_return_mean": None}
    started = time.perf_counter()
    streak = 0  # consecutive iterations with a mean return >= --stop-return

    def finished() -> bool:
        out_of_time = args.max_minutes > 0 and progress["wall_s"] >= 60 * args.max_minutes
        solved = args.stop_return != 0 and streak >= args.stop_patience
        return progress["env_steps"] >= args.total_env_steps or out_of_time or solved

    while not finished():
        result = algo.train()
        scalars = record_iteration(result, progress, started)
        step = progress["env_steps"]
        episode_return = scalars["train/episode_return_mean"]
        progress["episode_return_mean"] = None if episode_return is None else float(episode_return)
        streak = streak + 1 if episode_return is not None and episode_return >= args.stop_return else 0
        write_scalars(writer, scalars, step)
        writer.flush()
        shown_return = "       -" if episode_return is None else f"{episode_return:8.2f}"  # no episode ended yet
        print(f"iter {progress['iteration']:4d}  steps {step:8d}  return {shown_return}  "
              f"len {scalars['train/episode_len_mean'] or 0:6.1f}  {scalars['train/env_steps_per_s']:.0f} steps/s  "
              f"{progress['wall_s'] / 60:.1f} min", flush=True)
        if "audit" in result:
            print_audit(result["audit"])
        if progress["iteration"] % args.checkpoint_every == 0 and not finished():
            save_checkpoint(algo, run_dir, progress)

    checkpoint = save_checkpoint(algo, run_dir, progress)
    if args.audit_every:
        finish_audits_and_report(algo, run_dir)
    algo.stop()
    writer.close()
    ray.shutdown()
    module_path = export_module(checkpoint, args.export) if args.export else module_dir(checkpoint)

    # The evaluation reads the checkpoint back as a user would: RLModule.from_checkpoint, then our own loop.
    module = RLModule.from_checkpoint(str(Path(module_path).resolve()))
    returns = greedy_returns(greedy_action(module), args.env_id, args.eval_episodes, args.eval_seed)
    print(f"done: {progress['env_steps']} env steps, {progress['iteration']} iterations in "
          f"{progress['wall_s'] / 60:.1f} min")
    report_evaluation(run_dir, args.env_id, returns, args.eval_seed)
    print(f"algorithm checkpoint: {checkpoint}")
    print(f"module checkpoint: {module_dir(checkpoint)}")
    if args.export:
        print(f"module checkpoint exported to: {Path(args.export).resolve()}")
    print(f"args, progress, evaluation: {run_dir / 'args.json'}, {run_dir / 'progress.json'}, "
          f"{run_dir / 'evaluation.json'}")
    print(f"open it in TensorBoard: tensorboard --logdir {run_dir}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
