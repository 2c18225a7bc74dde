"""``dsage-ray maze eval``: evaluate an agent on a layout file."""

from __future__ import annotations

import argparse

from dsage_ray.domains.agent_help import agent_kinds_help
from dsage_ray.errors import InputError


def add_subparser(subparsers) -> None:
    """Registers ``maze`` (with its ``eval`` sub-command) on the top-level CLI's sub-parsers."""
    maze = subparsers.add_parser("maze", help="Maze domain tools")
    commands = maze.add_subparsers(dest="maze_command", required=True)
    ev = commands.add_parser("eval", help="evaluate an agent on a maze layout file",
                             description="Runs an agent on a layout for N episodes and prints the summary.")
    ev.add_argument("--agent", required=True, metavar="SPEC",
                    help=f"agent spec, of a kind the maze plays ({agent_kinds_help('maze')})")
    ev.add_argument("--layout", required=True, metavar="FILE",
                    help="plain-text layout: '#' wall, '.' empty, optional S/G; interior only")
    ev.add_argument("--episodes", type=int, default=50, help="episodes to run (default 50)")
    ev.add_argument("--seed", type=int, default=0, help="seed for headings and agent sampling (default 0)")
    ev.add_argument("--no-see-through-walls", dest="see_through_walls", action="store_false",
                    help="apply MiniGrid's occlusion mask (the ACCEL agent was trained without it)")
    ev.add_argument("--json", action="store_true", help="print one JSON object instead of a table")
    ev.add_argument("--render", metavar="OUT.png", help="also write a PNG of the level with the occupancy overlay")
    ev.set_defaults(handler=run_eval)


def run_eval(args: argparse.Namespace) -> int:
    """Handler of ``maze eval``; bad input ends it through :func:`dsage_ray.cli.main` in one line."""
    from dsage_ray.domains.maze import agents
    from dsage_ray.domains.maze.evaluate import evaluate
    from dsage_ray.domains.maze.layout import load_layout

    if args.episodes < 1:
        raise InputError(f"--episodes must be positive, got {args.episodes}")
    level = load_layout(args.layout)
    agent = agents.load_maze_agent(args.agent)
    result = evaluate(level, agent, episodes=args.episodes, seed=args.seed, see_through_walls=args.see_through_walls)
    if args.render:
        from dsage_ray.domains.maze.render import render_level

        render_level(level, result.occupancy, args.render, title=f"{args.agent} on {args.layout}")
    if args.json:
        print(result.to_json())
    else:
        lengths = result.episode_lengths
        print(f"layout            {args.layout} ({level.height}x{level.width}, {result.num_walls} walls)")
        print(f"agent             {args.agent}")
        print(f"episodes          {result.episodes} (seed {args.seed})")
        print(f"success rate      {result.success_rate:.3f}")
        print(f"mean path length  {result.mean_path_length:.1f}  (optimal {result.optimal_path_length}, "
              f"max {result.max_steps}; min {lengths.min()}, max {lengths.max()})")
        print(f"explored fraction {result.explored_fraction:.3f}")
        print(f"repeated visits   {result.repeated_visits:.1f}")
    return 0
