"""``dsage-ray gym eval``: play an agent on a gym level file (what each collection entry's ``reproduce`` runs)."""

from __future__ import annotations

import argparse
import json
import sys

from dsage_ray.domains.agent_help import agent_kinds_help
from dsage_ray.errors import InputError


def add_subparser(subparsers) -> None:
    """Registers ``gym`` (with its ``eval`` and ``spaces`` sub-commands) on the top-level CLI's sub-parsers."""
    gym = subparsers.add_parser("gym", help="gym domain tools (any Gymnasium environment)")
    commands = gym.add_subparsers(dest="gym_command", required=True)
    ev = commands.add_parser("eval", help="play an agent on a gym level file",
                             description="Plays an agent for N episodes of the level (a JSON file an audit wrote: "
                                         "the space and the parameter values) and prints what it did.")
    ev.add_argument("--agent", required=True, metavar="SPEC",
                    help=f"agent spec, of a kind the gym domain plays ({agent_kinds_help('gym')})")
    ev.add_argument("--level", required=True, metavar="FILE", help="a level file of a gym collection")
    ev.add_argument("--episodes", type=int, default=10, help="episodes (default 10)")
    ev.add_argument("--seed", type=int, default=0, help="the evaluation seed (default 0)")
    ev.add_argument("--json", action="store_true", help="print one JSON object instead of a table")
    ev.set_defaults(handler=run_eval)
    spaces = commands.add_parser("spaces", help="list the shipped parameter spaces")
    spaces.set_defaults(handler=list_spaces)


def run_eval(args: argparse.Namespace) -> int:
    """Handler of ``gym eval``: the numbers a collection entry records for this level, seed and episodes."""
    from dsage_ray.agents import load_agent
    from dsage_ray.domains.gym.domain import read_level
    from dsage_ray.domains.gym.simulator import make_env, run_episodes

    if args.episodes < 1:
        raise InputError(f"--episodes must be positive, got {args.episodes}")
    space, values = read_level(args.level)
    from dsage_ray.domains.gym.setup_hook import user_code_notices

    for notice in user_code_notices(space):  # a level file received from someone else may run code: say so first
        print(notice, file=sys.stderr)
    env = make_env(space, values)
    try:
        agent = load_agent(args.agent, observation_space=env.observation_space, action_space=env.action_space,
                           env=env)
    finally:
        env.close()
    played = run_episodes(space, agent, values, seed=args.seed, episodes=args.episodes)
    summary = {"env": space.env_id, "values": values, "episodes": len(played.returns), "seed": args.seed,
               "success_rate": float(played.success.mean()), "failure_rate": float(1 - played.success.mean()),
               "mean_return": float(played.returns.mean()), "min_return": float(played.returns.min()),
               "mean_length": float(played.lengths.mean())}
    if args.json:
        print(json.dumps(summary))
        return 0
    print(f"environment   {space.env_id}  ({', '.join(f'{k}={v:.4g}' if isinstance(v, float) else f'{k}={v}' for k, v in values.items())})")
    print(f"agent         {args.agent}")
    test = space.fault.describe() if space.fault is not None else f"success: {space.success.describe()}"
    print(f"episodes      {summary['episodes']} (seed {args.seed}); {test}")
    print(f"success rate  {summary['success_rate']:.3f}")
    print(f"return        mean {summary['mean_return']:.1f}, worst {summary['min_return']:.1f}")
    print(f"length        mean {summary['mean_length']:.1f}")
    return 0


def list_spaces(args: argparse.Namespace) -> int:
    """Handler of ``gym spaces``: each shipped space, its environment and parameters."""
    from dsage_ray.domains.gym.space import build_space, read_space_tables, shipped_spaces

    for name in shipped_spaces():
        tables, source = read_space_tables(name)
        space = build_space(tables, source=source)
        print(f"{name}: {space.env_id}, audit measures {', '.join(space.audit_measures)}; {source}")
        for p in space.params:
            print(f"  {p.describe()}")
    return 0
