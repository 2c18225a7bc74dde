"""``dsage-ray gridpath eval``: one agent on one level file (what an audit's reproduce commands run)."""

from __future__ import annotations

import argparse
import json

from dsage_ray.errors import InputError


def add_subparser(subparsers) -> None:
    """Registers ``gridpath eval`` on the top-level CLI's sub-parsers."""
    gridpath = subparsers.add_parser("gridpath", help="GridPath domain tools")
    commands = gridpath.add_subparsers(dest="gridpath_command", required=True)
    ev = commands.add_parser("eval", help="evaluate an agent on a gridpath level file")
    ev.add_argument("--agent", default="bfs", metavar="SPEC", help="bfs or bfs:MOVES (default bfs)")
    ev.add_argument("--level", required=True, metavar="FILE", help="a square of '#' walls and '.' free cells")
    ev.set_defaults(handler=run_eval)


def run_eval(args: argparse.Namespace) -> int:
    """Prints the evaluation as one JSON object: ``success_rate``, ``path_length``, ``objective``."""
    from dsage_ray_gridpath.domain import GridPathDomain, parse_level
    from dsage_ray_gridpath.plugin import GridPathConfig

    try:
        walls = parse_level(open(args.level).read(), source=args.level)
        domain = GridPathDomain(config=GridPathConfig(size=len(walls), agent=args.agent, objective="failure"))
    except (OSError, ValueError) as exc:
        raise InputError(str(exc)) from None
    result = domain.evaluate(walls.ravel(), seed=0)
    print(json.dumps({"success_rate": domain.success_rate(result), "path_length": result.info["path_length"],
                      "objective": result.objective}))
    return 0
