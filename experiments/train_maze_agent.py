"""Train a Maze agent with PPO on RLlib's new API stack (CleanRL-style: one file, one config dataclass).

The environment is :class:`maze_training_env.RandomMazeEnv` (``experiments/maze_training_env.py``, beside this
script): a fresh random valid 16×16 maze every episode, built on the project's MiniGrid ``MazeEnv``. A curriculum
moves the goal from a few steps away to the furthest cell (the evaluation setting) over ``curriculum_steps`` env
steps. The policy is :class:`dsage_ray.agents.rllib_module.MazeRLModule` (a small CNN; ``--use-lstm`` adds an
LSTM).

Every ``eval_every`` iterations the current module is evaluated the way audits evaluate agents (our batched
simulator, ``rllib:`` loader semantics) on a fixed set of random valid mazes; that success rate, the
curriculum position and RLlib's own metrics go to TensorBoard under ``tb_logs/<run_name>/``.

Usage (``--help`` lists every flag of :class:`Args` with its description and default; a boolean flag ``--x``
is switched off with ``--no-x``)::

    nice -n 10 python experiments/train_maze_agent.py --run-name ppo_maze --total-env-steps 400000
    nice -n 10 python experiments/train_maze_agent.py --run-name ppo_maze --resume   # continue it
    tensorboard --logdir tb_logs

Audits while training (``--audit-every N``, ``dsage_ray.integrations.rllib.AuditCallback``): every N
iterations the current module is saved to ``tb_logs/<run_name>/checkpoints/iter_<N>`` and audited
(the regression suite of earlier audits' failures re-evaluated, then a short warm-started DSAGE search of
``--audit-budget`` evaluations whose new failures join the suite); the series lives in
``tb_logs/<run_name>/audit_series`` and its numbers go to the run's TensorBoard under ``audit/...`` with
step = env steps. The audits run in a Ray actor with a CPU of its own while training goes on (one at a time:
one that falls due while another runs is skipped with a warning; the end of training waits for the last);
``--no-audit-background`` audits between iterations instead. A failed audit logs one warning line; training
goes on::

    nice -n 10 python experiments/train_maze_agent.py --run-name ppo_audited --audit-every 25 --audit-budget 30

Fine-tuning a trained module (``--init-from``): the weights of an ``rllib:`` checkpoint start the run (the optimiser
state starts fresh), e.g. to continue training the shipped agent on the failures an audit found::

    nice -n 10 python experiments/train_maze_agent.py --run-name ppo_fixed --init-from ppo_maze --curriculum-steps 0 \
        --total-env-steps 200000 --train-on-collection tb_logs/audit_mine

Training on found failures (``--train-on-collection DIR``): a share (``--collection-share``, default 0.25) of
the episodes replays a level of an audit collection (``DIR`` is the collection folder, or an audit folder
holding ``collection/``) instead of a fresh random maze, drawn from the env's seeded rng::

    nice -n 10 python experiments/train_maze_agent.py --run-name ppo_mixed --train-on-collection tb_logs/audit_mine

The run folder holds ``checkpoint/`` (the latest full algorithm checkpoint, what ``--resume`` reads; also
loadable as ``rllib:tb_logs/<run>/checkpoint``), ``progress.json`` and TensorBoard event files.
``--export DIR`` copies the module-only checkpoint (a few hundred KB) there, e.g. into the package assets.
"""

from __future__ import annotations

import dataclasses
import json
import shutil
import sys
import time
from pathlib import Path

import tyro

from dsage_ray.integrations import DEFAULT_AUDIT_BUDGET, DEFAULT_PRESET
from dsage_ray.integrations.training import (audit_callback, check_audit_flags, export_module,
                                             finish_audits_and_report, module_dir, print_audit, record_iteration,
                                             save_checkpoint, write_scalars)


ENV_NAME = "dsage_ray/RandomMaze-v0"
#: This script's folder, which holds its training env (``maze_training_env.py``).
SCRIPT_DIR = Path(__file__).resolve().parent


@dataclasses.dataclass
class Args:
    """The script's flags: ``--help`` prints each with the description under it."""

    run_name: str = "ppo_maze"
    """folder under tb_logs/ that holds the run"""
    seed: int = 0
    """RLlib's seed (env runners, module initialisation)"""
    total_env_steps: int = 400_000
    """stop after this many environment steps (all iterations together, across resumes)"""
    max_minutes: float = 0.0
    """also stop after this much wall-clock training time (0 = no limit)"""
    resume: bool = False
    """continue tb_logs/<run_name>/checkpoint"""
    init_from: str = ""
    """start from this RLModule's weights instead of a fresh initialisation: an ``rllib:`` spec or folder (a
    shipped name such as ``ppo_maze``, a module-only or algorithm checkpoint) of the same --hidden/--use-lstm;
    ignored with --resume, whose checkpoint already holds the weights (empty = fresh weights)"""
    export: str = ""
    """at the end, copy the module-only checkpoint to this folder (empty = no export)"""

    # Environment and curriculum
    num_envs: int = 8
    """vectorised envs in the (single, local) env runner"""
    curriculum_steps: int = 200_000
    """env steps over which the goal moves from nearby to the furthest cell"""
    see_through_walls: bool = True
    """MiniGrid's observation setting, in training and in the script's evaluations (audits: the config's
    maze.see_through_walls)"""

    # PPO
    lr: float = 5e-4
    """Adam learning rate"""
    gamma: float = 0.99
    """discount factor"""
    gae_lambda: float = 0.95
    """GAE lambda"""
    train_batch_size: int = 4096
    """env steps per PPO iteration (train_batch_size_per_learner)"""
    minibatch_size: int = 512
    """SGD minibatch size"""
    num_epochs: int = 4
    """passes over each iteration's batch"""
    entropy_coeff: float = 0.01
    """entropy bonus coefficient"""
    vf_loss_coeff: float = 0.5
    """value-function loss coefficient"""
    clip_param: float = 0.2
    """PPO clip range"""

    # Module
    hidden: int = 128
    """width of the MazeRLModule's MLP (and LSTM)"""
    use_lstm: bool = False
    """add an LSTM after the MLP (a recurrent policy)"""
    max_seq_len: int = 32
    """LSTM training sequence length (only with --use-lstm)"""

    # Bookkeeping
    checkpoint_every: int = 5
    """iterations between checkpoints"""
    eval_every: int = 10
    """iterations between evaluations on the fixed maze set (0 = never)"""
    eval_mazes: int = 20
    """random valid mazes in the fixed evaluation set"""
    eval_episodes: int = 10
    """episodes per evaluation maze"""
    num_cpus: int = 2
    """logical CPUs of the local Ray instance"""
    torch_threads: int = 1
    """torch threads for the learner (the machine is shared)"""

    # Audits while training (dsage_ray.integrations.rllib.AuditCallback)
    audit_every: int = 0
    """training iterations between audits of the current policy (0 = no audits)"""
    audit_budget: int = DEFAULT_AUDIT_BUDGET
    """real evaluations of each audit's DSAGE search (at least 20: its first 20 are random levels)"""
    audit_preset: str = DEFAULT_PRESET
    """the audits' preset (their search settings; --audit-budget replaces its budget)"""
    audit_episodes: int = 0
    """episodes per level when an audit re-evaluates the suite and its new failures (0 = the preset's: tiny 5)"""
    audit_background: bool = True
    """audit in a Ray actor with a CPU of its own while training goes on (--no-audit-background: in the training
    process, between iterations)"""

    # Training on an audit's failures
    train_on_collection: str = ""
    """an audit collection folder (or an audit folder holding collection/) whose levels replace a share of the
    random training mazes (empty = random mazes only)"""
    collection_share: float = 0.25
    """probability that an episode plays a level of --train-on-collection instead of a random maze"""


def parse_args(argv: list[str] | None = None) -> Args:
    """``Args`` from the command line (``--help`` lists every flag; a boolean ``--x`` has ``--no-x``)."""
    return tyro.cli(Args, args=argv, description=__doc__.split("\n\n")[0])


def training_env_creator():
    """``maze_training_env.make_random_maze_env``, the env creator, imported from this script's folder.

    The folder is on ``sys.path`` when the script runs (and Ray adds it to its workers' path), but not when a
    test, a benchmark or ``train_on_collection.py`` imports the script as a module: it is added then.
    """
    if str(SCRIPT_DIR) not in sys.path:
        sys.path.insert(0, str(SCRIPT_DIR))
    from maze_training_env import make_random_maze_env

    return make_random_maze_env


def build_config(args: Args, levels: list[str] | None = None):
    """The PPOConfig: our env creator, our RLModule, one local env runner, one local learner.

    ``levels`` (layout texts, :func:`collection_levels`) are mixed into the training mazes with
    probability ``args.collection_share``.
    """
    from ray.rllib.algorithms.ppo import PPOConfig
    from ray.rllib.core.rl_module.rl_module import RLModuleSpec
    from ray.tune.registry import register_env

    from dsage_ray.agents.rllib_module import MazeRLModule

    # Registered by name: RLlib ships the creator to every env runner through its registry.
    register_env(ENV_NAME, training_env_creator())
    model_config = {"hidden": args.hidden, "use_lstm": args.use_lstm}
    if args.use_lstm:
        model_config["max_seq_len"] = args.max_seq_len
    return (
        PPOConfig()
        .environment(ENV_NAME, env_config={"difficulty": 0.0, "see_through_walls": args.see_through_walls,
                                           **({"levels": list(levels), "level_share": args.collection_share}
                                              if levels else {})})
        # Sampling in the driver process: on 2 shared cores a remote env runner only adds copies.
        .env_runners(num_env_runners=0, num_envs_per_env_runner=args.num_envs)
        .learners(num_learners=0)
        .rl_module(rl_module_spec=RLModuleSpec(module_class=MazeRLModule, model_config=model_config))
        .training(
            lr=args.lr,
            gamma=args.gamma,
            lambda_=args.gae_lambda,
            train_batch_size_per_learner=args.train_batch_size,
            minibatch_size=args.minibatch_size,
            num_epochs=args.num_epochs,
            entropy_coeff=args.entropy_coeff,
            vf_loss_coeff=args.vf_loss_coeff,
            clip_param=args.clip_param,
        )
        .debugging(seed=args.seed)
    )


def load_audit_collection(folder: str | Path, *, name: str):
    """The :class:`~dsage_ray.audit.results.Collection` in ``folder``: a collection folder, or an audit folder
    holding one in ``collection/``. InputError starting with ``name`` when there is none or it is unreadable."""
    from dsage_ray.audit.results import Collection
    from dsage_ray.errors import InputError

    path = Path(folder)
    if not path.is_dir():
        raise InputError(f"{name}: no such folder")
    if not (path / "collection.json").is_file() and (path / "collection" / "collection.json").is_file():
        path = path / "collection"  # an audit folder
    if not (path / "collection.json").is_file():
        raise InputError(f"{name}: no collection.json (expected an audit's collection folder, or an audit folder "
                         f"holding collection/)")
    try:
        return Collection.load(path)
    except (ValueError, KeyError, TypeError) as exc:
        raise InputError(f"{name}: {exc}") from None


def collection_levels(folder: str | Path, *, height: int = 16, width: int = 16) -> list[str]:
    """The layout texts of an audit collection's levels, for ``--train-on-collection``.

    ``folder`` is a collection folder (``collection.json`` and ``levels/``) or an audit folder holding one
    in ``collection/``. Raises InputError, naming the folder and the problem, when it is not a Maze
    collection with at least one readable level of the training size.
    """
    from dsage_ray.domains.maze.layout import format_layout, load_layout
    from dsage_ray.errors import InputError

    name = f"--train-on-collection {folder}"
    collection = load_audit_collection(folder, name=name)
    if collection.domain != "maze":
        raise InputError(f"{name}: a {collection.domain} collection; the maze agent trains on maze levels")
    if not collection.levels:
        raise InputError(f"{name}: the collection holds no levels")
    texts = []
    for level in collection.levels:
        try:
            maze = load_layout(level.level_path)
        except InputError as exc:  # LayoutError: names the file and the line
            raise InputError(f"{name}: {exc}") from None
        if (maze.height, maze.width) != (height, width):
            raise InputError(f"{name}: {level.level_path} is {maze.height}x{maze.width}; the training mazes are "
                             f"{height}x{width}")
        texts.append(format_layout(maze))
    return texts


def init_module_dir(spec: str) -> Path:
    """The RLModule folder that ``--init-from`` names (``rllib:`` prefix optional); InputError when there is none."""
    from dsage_ray.agents.base import AgentError
    from dsage_ray.agents.rllib import resolve_module_dir
    from dsage_ray.errors import InputError

    try:
        return resolve_module_dir(spec.removeprefix("rllib:")).resolve()
    except AgentError as exc:
        raise InputError(f"--init-from {spec}: {exc}") from None


def load_initial_weights(algo, module: Path, spec: str) -> None:
    """Puts the weights of ``module`` into the learner and the env runners; InputError when they do not fit."""
    from dsage_ray.errors import InputError

    component = str(Path("learner_group") / "learner" / "rl_module" / "default_policy")
    try:
        algo.restore_from_path(str(module), component=component)
    except (RuntimeError, KeyError, ValueError) as exc:  # torch's load_state_dict: missing keys or other shapes
        # torch names the module, then one line per mismatch: the first mismatch says enough.
        lines = [line.strip() for line in str(exc).splitlines() if line.strip()] or [type(exc).__name__]
        raise InputError(f"--init-from {spec}: its weights do not fit this run's module (--hidden, --use-lstm): "
                         f"{' '.join(lines[:2])}") from None


def difficulty_at(env_steps: int, args: Args) -> float:
    """Curriculum position: linear in env steps, 1 (furthest goal) from ``curriculum_steps`` on."""
    return 1.0 if args.curriculum_steps <= 0 else min(1.0, env_steps / args.curriculum_steps)


def set_difficulty(algo, difficulty: float) -> None:
    """Pushes the curriculum position into every env of every env runner (here: the local one)."""
    algo.env_runner_group.foreach_env_runner(lambda runner: runner.env.unwrapped.set_attr("difficulty", difficulty))


def evaluate_module(module_dir: Path, args: Args) -> dict[str, float]:
    """Success rate and mean path length on a fixed set of random valid mazes, through the ``rllib:`` loader."""
    import numpy as np

    from dsage_ray.domains.maze.agents import load_maze_agent
    from dsage_ray.domains.maze.generator import random_valid_levels
    from dsage_ray.domains.maze import evaluate

    agent = load_maze_agent(f"rllib:{module_dir}")
    results = [evaluate(level, agent, episodes=args.eval_episodes, seed=i, see_through_walls=args.see_through_walls)
               for i, level in enumerate(random_valid_levels(args.eval_mazes, seed=12345))]
    return {"success_rate": float(np.mean([r.success_rate for r in results])),
            "mean_path_length": float(np.mean([r.mean_path_length for r in results]))}


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    from dsage_ray.errors import InputError

    levels = None
    try:
        check_audit_flags(args)
        if not 0.0 <= args.collection_share <= 1.0:
            raise InputError(f"--collection-share {args.collection_share} is not a probability in [0, 1]")
        if args.train_on_collection:
            levels = collection_levels(args.train_on_collection)
        initial_module = init_module_dir(args.init_from) if args.init_from and not args.resume else None
    except InputError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    import ray
    import torch
    from tensorboardX import SummaryWriter

    from dsage_ray.ray.session import start_ray

    torch.set_num_threads(args.torch_threads)
    run_dir = (Path("tb_logs") / args.run_name).resolve()  # RLlib reads paths as URIs: they must be absolute
    if run_dir.exists() and not args.resume and (run_dir / "checkpoint").exists():
        print(f"{run_dir} already holds a run; pass --resume to continue it or pick another --run-name",
              file=sys.stderr)
        return 2
    new_run = not run_dir.exists()
    run_dir.mkdir(parents=True, exist_ok=True)
    (run_dir / "args.json").write_text(json.dumps(dataclasses.asdict(args), indent=2))

    if levels:
        print(f"training on {len(levels)} levels of {args.train_on_collection} in a share {args.collection_share} "
              f"of the episodes", flush=True)

    start_ray(num_cpus=args.num_cpus, log_to_driver=False)
    writer = SummaryWriter(str(run_dir))
    config = build_config(args, levels)
    if args.audit_every:
        config.callbacks(audit_callback(args, run_dir, writer))
    algo = config.build_algo()
    progress = {"iteration": 0, "env_steps": 0, "wall_s": 0.0}
    if args.resume:
        algo.restore_from_path(str((run_dir / "checkpoint").resolve()))
        progress = json.loads((run_dir / "progress.json").read_text())
        print(f"resumed at iteration {progress['iteration']}, {progress['env_steps']} env steps")
    elif initial_module is not None:
        try:
            load_initial_weights(algo, initial_module, args.init_from)
        except InputError as exc:
            algo.stop()
            writer.close()
            ray.shutdown()
            if new_run:  # nothing half-written: the folder held only this attempt's args and empty event file
                shutil.rmtree(run_dir, ignore_errors=True)
            print(f"error: {exc}", file=sys.stderr)
            return 2
        print(f"started from the weights of {initial_module}", flush=True)

    started = time.perf_counter() - progress["wall_s"]
    def finished() -> bool:
        out_of_time = args.max_minutes > 0 and progress["wall_s"] >= 60 * args.max_minutes
        return progress["env_steps"] >= args.total_env_steps or out_of_time

    while not finished():
        set_difficulty(algo, difficulty_at(progress["env_steps"], args))
        result = algo.train()
        scalars = record_iteration(result, progress, started)
        step = progress["env_steps"]
        scalars["train/difficulty"] = difficulty_at(step, args)
        write_scalars(writer, scalars, step)
        print(f"iter {progress['iteration']:4d}  steps {step:8d}  return {scalars['train/episode_return_mean'] or 0:.3f}  "
              f"len {scalars['train/episode_len_mean'] or 0:6.1f}  difficulty {scalars['train/difficulty']:.2f}  "
              f"{scalars['train/env_steps_per_s']:.0f} steps/s", flush=True)
        if "audit" in result:
            print_audit(result["audit"])

        last = finished()
        if progress["iteration"] % args.checkpoint_every == 0 or last:
            checkpoint = save_checkpoint(algo, run_dir, progress)
            if args.eval_every and (progress["iteration"] % args.eval_every == 0 or last):
                scores = evaluate_module(module_dir(checkpoint), args)
                for name, value in scores.items():
                    writer.add_scalar(f"eval/{name}", value, step)
                print(f"  eval on {args.eval_mazes} fixed mazes: success {scores['success_rate']:.3f}  "
                      f"mean path length {scores['mean_path_length']:.1f}", flush=True)
        writer.flush()

    checkpoint = save_checkpoint(algo, run_dir, progress)
    if args.audit_every:
        finish_audits_and_report(algo, run_dir)
    if args.export:
        print(f"module checkpoint exported to {export_module(checkpoint, args.export)}")
    writer.close()
    algo.stop()
    ray.shutdown()
    print(f"done: {progress['env_steps']} env steps in {progress['wall_s'] / 60:.1f} min; checkpoint {checkpoint}")
    print(f"open it in TensorBoard: tensorboard --logdir {run_dir}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
