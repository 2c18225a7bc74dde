"""What the training scripts in ``experiments/`` share (they are run by file path, so shared code lives here).

The ``--audit-*`` flags of the RLlib training scripts (``experiments/train_maze_agent.py``,
``experiments/train_gym_agent.py``): their checks, the callback they configure and the lines they print.
A script's ``Args`` declares ``audit_every``, ``audit_budget``, ``audit_preset``, ``audit_episodes``,
``audit_background``, ``seed`` and ``num_cpus``; the script calls :func:`check_audit_flags` before anything
runs, ``config.callbacks(audit_callback(args, run_dir, writer, domain=..., overrides=...))`` when
``--audit-every`` is set, :func:`print_audit` on ``result["audit"]`` after each iteration, and
:func:`finish_audits_and_report` after the last one (before ``algo.stop()``).

The RLlib scripts' bookkeeping: :func:`record_iteration` and :func:`write_scalars` after each ``algo.train()``,
:func:`save_checkpoint`, :func:`module_dir` and :func:`export_module`.

The Gymnasium scripts' (``experiments/train_gym_agent.py``, ``experiments/train_sb3_agent.py``) env flags
(:func:`check_env_flags`) and final greedy evaluation (:func:`greedy_returns`, :func:`report_evaluation`).

Importing this module imports neither Ray nor torch.
"""

from __future__ import annotations

import json
import shutil
import tempfile
from pathlib import Path
from typing import Any, Callable, Mapping

from dsage_ray.domains.registry import DEFAULT_DOMAIN
from dsage_ray.integrations.defaults import DEFAULT_EPISODES, DEFAULT_OVERRIDES


def check_audit_flags(args: Any, *, domain: str = DEFAULT_DOMAIN, overrides: Mapping[str, Any] | None = None) -> None:
    """Raises InputError, naming the flags, when the ``--audit-*`` flags cannot work together.

    With ``--audit-every`` set, the audits' config (``domain``, the preset, the budget, ``overrides`` over
    :data:`~dsage_ray.integrations.defaults.DEFAULT_OVERRIDES`) is checked too, so that a budget below the search's
    ``n_rand`` or an unknown preset stops the script before training rather than skipping every audit.
    """
    from dsage_ray.errors import InputError

    if args.audit_every < 0 or args.audit_budget < 1 or args.audit_episodes < 0:
        raise InputError("--audit-every and --audit-episodes must be >= 0, --audit-budget >= 1")
    if args.audit_every and args.audit_background and args.num_cpus < 2:
        raise InputError(f"background audits need a CPU of their own: --num-cpus {args.num_cpus} leaves none "
                         f"(raise it, or audit between iterations with --no-audit-background)")
    if args.audit_every:
        from dsage_ray.audit.collection import audit_config

        try:
            audit_config(domain=domain, agent=None, preset=args.audit_preset, budget=args.audit_budget,
                         seed=args.seed, overrides={**DEFAULT_OVERRIDES, **dict(overrides or {})})
        except ValueError as exc:  # InputError, ConfigError
            raise InputError(f"the audits' settings (--audit-preset {args.audit_preset}, --audit-budget "
                             f"{args.audit_budget}): {exc}") from None


def audit_callback(args: Any, run_dir: Path, writer: Any, *, domain: str = DEFAULT_DOMAIN,
                   overrides: Mapping[str, Any] | None = None):
    """``--audit-every``: the RLlib callback factory (modules in ``run_dir/checkpoints``, series in
    ``run_dir/audit_series``, scalars to ``writer``), auditing in ``domain`` with the config ``overrides``."""
    from dsage_ray.integrations.rllib import AuditCallback

    return AuditCallback.configured(audit_every=args.audit_every, audit_budget=args.audit_budget, out_dir=run_dir,
                                    writer=writer, preset=args.audit_preset, seed=args.seed,
                                    background=args.audit_background, domain=domain,
                                    overrides=dict(overrides or {}),
                                    episodes=args.audit_episodes or DEFAULT_EPISODES)


def print_audit(audit: Mapping[str, Any]) -> None:
    """One line per audit that ended (``result["audit"]``)."""
    success = audit.get("suite_success_rate")
    print(f"  audit of iteration {audit.get('checkpoint_iteration', '?')}: suite success "
          f"{'-' if success is None else f'{success:.3f}'}  fixed {audit.get('fixed', 0):.0f}  "
          f"regressed {audit.get('regressed', 0):.0f}  new failures {audit.get('new_failures', 0):.0f}  "
          f"never solved {audit.get('never_solved', 0):.0f}  {audit.get('wall_time', 0):.0f} s", flush=True)


def finish_audits_and_report(algo: Any, run_dir: Path) -> None:
    """After the last iteration: waits for a background audit still running, prints the audits that ended here
    and where the series is."""
    from dsage_ray.integrations.rllib import finish_audits

    print("waiting for the last audit ...", flush=True)
    for iteration, record, _ in finish_audits(algo):
        if record is not None:
            print_audit({k.removeprefix("audit/"): v for k, v in record.scalars().items()}
                        | {"checkpoint_iteration": iteration})
    print(f"audit series: {run_dir / 'audit_series'}", flush=True)


# --- RLlib bookkeeping --------------------------------------------------------------------------------------------


def record_iteration(result: Mapping[str, Any], progress: dict, started: float) -> dict[str, Any]:
    """Counts one ``algo.train()`` ``result`` into ``progress`` (``iteration``, ``env_steps``, ``wall_s`` since the
    ``time.perf_counter()`` value ``started``) and returns the iteration's scalars by TensorBoard tag (a value
    RLlib did not report, e.g. the return before any episode ended, is None)."""
    import time

    progress["iteration"] += 1
    progress["env_steps"] += int(result["env_runners"]["num_env_steps_sampled"])
    progress["wall_s"] = time.perf_counter() - started
    runners = result["env_runners"]
    learner = result["learners"]["default_policy"]
    return {
        "train/episode_return_mean": runners.get("episode_return_mean"),
        "train/episode_len_mean": runners.get("episode_len_mean"),
        "train/env_steps_per_s": progress["env_steps"] / max(progress["wall_s"], 1e-9),
        "loss/policy": learner.get("policy_loss"),
        "loss/vf": learner.get("vf_loss"),
        "loss/entropy": learner.get("entropy"),
    }


def write_scalars(writer: Any, scalars: Mapping[str, Any], step: int) -> None:
    """The scalars that are not None to the TensorBoard ``writer`` at ``step``."""
    for tag, value in scalars.items():
        if value is not None:
            writer.add_scalar(tag, float(value), step)


def module_dir(checkpoint: Path) -> Path:
    """The RLModule folder inside an algorithm checkpoint (what ``RLModule.from_checkpoint`` and the ``rllib:``
    loader read)."""
    return checkpoint / "learner_group" / "learner" / "rl_module" / "default_policy"


def save_checkpoint(algo: Any, run_dir: Path, progress: Mapping[str, Any]) -> Path:
    """Writes the full algorithm checkpoint to a staging folder, then swaps it in for ``run_dir/checkpoint`` (a
    crash keeps the old one), and ``progress`` to ``run_dir/progress.json``; returns the checkpoint."""
    from dsage_ray.io import atomic_write_json, replace_dir

    staging = Path(tempfile.mkdtemp(prefix=".checkpoint.", dir=run_dir))
    algo.save_to_path(str(staging))
    replace_dir(staging, run_dir / "checkpoint")
    atomic_write_json(run_dir / "progress.json", progress)
    return run_dir / "checkpoint"


def export_module(checkpoint: Path, export: str | Path) -> Path:
    """``--export``: copies the module-only checkpoint of ``checkpoint`` to ``export`` (replacing what was there)."""
    export = Path(export)
    if export.exists():
        shutil.rmtree(export)
    shutil.copytree(module_dir(checkpoint), export)
    return export


# --- Gymnasium scripts: env flags and the final greedy evaluation -------------------------------------------------


def check_env_flags(args: Any) -> dict:
    """``--env-config`` as a dict, after checking that it is a JSON object and that ``--env-id`` is registered;
    InputError, naming the flag, when not."""
    from dsage_ray.errors import InputError

    try:
        env_config = json.loads(args.env_config)
        if not isinstance(env_config, dict):
            raise ValueError("not a JSON object")
    except ValueError as exc:
        raise InputError(f"--env-config {args.env_config!r}: {exc}") from None
    import gymnasium as gym

    try:
        gym.spec(args.env_id)
    except gym.error.Error as exc:
        raise InputError(f"--env-id {args.env_id}: {exc}") from None
    return env_config


def greedy_returns(act: Callable[[Any, Any], Any], env_id: str, episodes: int, seed: int) -> list[float]:
    """Returns of ``episodes`` episodes of ``gymnasium.make(env_id)`` (seeds ``seed`` onwards), each step's action
    ``act(observation, action_space)``."""
    import gymnasium as gym

    env = gym.make(env_id)
    returns = []
    for episode in range(episodes):
        obs, _ = env.reset(seed=seed + episode)
        total, done = 0.0, False
        while not done:
            obs, reward, terminated, truncated, _ = env.step(act(obs, env.action_space))
            total += float(reward)
            done = terminated or truncated
        returns.append(total)
    env.close()
    return returns


def report_evaluation(run_dir: Path, env_id: str, returns: list[float], seed: int, **extra: Any) -> dict[str, Any]:
    """Writes ``run_dir/evaluation.json`` (``env_id``, ``extra``, the episodes, their seeds and the returns' mean,
    std, min and max), prints its line and returns it."""
    import numpy as np

    evaluation = {"env_id": env_id, **extra, "episodes": len(returns), "seeds": [seed, seed + len(returns) - 1],
                  "mean_return": float(np.mean(returns)), "std_return": float(np.std(returns)),
                  "min_return": float(np.min(returns)), "max_return": float(np.max(returns))}
    (run_dir / "evaluation.json").write_text(json.dumps(evaluation, indent=2))
    print(f"greedy evaluation on {env_id} (default parameters), {len(returns)} episodes, seeds "
          f"{seed}..{seed + len(returns) - 1}: mean return {evaluation['mean_return']:.2f} "
          f"(std {evaluation['std_return']:.2f}, min {evaluation['min_return']:.2f}, "
          f"max {evaluation['max_return']:.2f})")
    return evaluation
