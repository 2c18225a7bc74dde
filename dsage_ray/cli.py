"""``dsage-ray``: the command-line interface (thin: it parses, then calls the library's API)."""

from __future__ import annotations

import argparse
import importlib
import os
import shlex
import sys

from dsage_ray import __version__, surrogate_cli
from dsage_ray.audit import cli as audit_cli
from dsage_ray.cli_args import add_config_arguments, add_ray_arguments, config_overrides, load_run_config
from dsage_ray.errors import DsageError, Interrupted, describe

#: Help layout of every command: the description and the examples epilog keep their line breaks.
HELP_FORMAT = argparse.RawDescriptionHelpFormatter

RUN_EXAMPLES = """\
examples:
  dsage-ray run experiments/configs/maze_dsage.toml --preset tiny --local      # a smoke run, no Ray
  dsage-ray run experiments/configs/maze_dsage.toml --preset cpu --workers 4   # through Ray Tune
  dsage-ray run experiments/configs/maze_dsage.toml --set maze.agent=rllib:ppo_maze --set budget=300
  dsage-ray run experiments/configs/maze_dsage.toml --preset cpu --out tb_logs --resume   # after Ctrl+C
  dsage-ray config experiments/configs/maze_dsage.toml --preset cpu                       # the keys it uses
"""

ABLATE_EXAMPLES = """\
examples:
  dsage-ray ablate experiments/configs/maze_dsage.toml --preset cpu            # the paper's variants x 5 seeds
  dsage-ray ablate experiments/configs/maze_dsage.toml --preset tiny --variants dsage,map_elites --seeds 2
  dsage-ray ablate experiments/configs/maze_dsage.toml --preset cpu --grid surrogate.epochs=10,50 --seeds 3
  python experiments/summarize.py tb_logs/maze_dsage                            # the table and the plot
"""


def domain_command_modules() -> list[str]:
    """The domains' command modules, named by their registrations (``dsage-ray maze ...``); each exposes
    ``add_subparser(subparsers)``. Plug-in domains bring theirs, so they are found by name."""
    from dsage_ray.domains import domain_names, get_domain

    modules = []
    for name in domain_names():
        try:
            spec = get_domain(name)
        except DsageError:
            continue  # a plug-in that does not load has no sub-command; naming its domain says why
        if spec.cli:
            modules.append(spec.cli)
    return modules


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="dsage-ray", description="DSAGE on Ray: search for diverse levels where an agent fails.",
        epilog="start with: dsage-ray audit --help  (Python: import dsage_ray; help(dsage_ray.run_audit))")
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    subparsers = parser.add_subparsers(dest="command", required=True)
    _add_run(subparsers)
    _add_ablate(subparsers)
    _add_config(subparsers)
    audit_cli.add_subparser(subparsers)
    surrogate_cli.add_subparser(subparsers)
    for module_name in domain_command_modules():
        try:
            module = importlib.import_module(module_name)
        except ImportError as exc:
            # A domain whose optional dependencies are missing simply has no sub-command.
            if exc.name and exc.name.startswith("dsage_ray"):
                continue
            raise
        module.add_subparser(subparsers)
    return parser


def _add_run(subparsers) -> None:
    parser = subparsers.add_parser(
        "run", help="run DSAGE (or a baseline) from a config file", formatter_class=HELP_FORMAT,
        description="Runs DSAGE, or the baseline the config's variant names, to its evaluation budget: through "
                    "Ray Tune (one trial) unless --local.\nThe agents are loaded first, so a bad one fails "
                    "before anything starts. Python: dsage_ray.run().",
        epilog=RUN_EXAMPLES)
    parser.add_argument("config", help="a TOML/JSON config, e.g. experiments/configs/maze_dsage.toml")
    add_config_arguments(parser.add_argument_group("config"))
    output = parser.add_argument_group("output")
    output.add_argument("--out", help="--local: the run folder (default tb_logs/<name>, <name> being the config's "
                                      "name key, e.g. tb_logs/maze_dsage); through Tune: the storage folder or URI "
                                      "(default tb_logs; s3://, gs://, file://), the run folder being "
                                      "<out>/<name>/<trial>")
    add_ray_arguments(parser, resume="continue the run in --out from its last checkpoint")
    parser.set_defaults(handler=_run)


def _add_ablate(subparsers) -> None:
    parser = subparsers.add_parser(
        "ablate", help="run a grid (the paper's variant x seed, or any config keys) as one Tune experiment",
        formatter_class=HELP_FORMAT,
        description="Runs a grid of DSAGE runs as one Ray Tune experiment; every grid point is checked before Ray "
                    "starts.\nPython: dsage_ray.ablate().",
        epilog=ABLATE_EXAMPLES)
    parser.add_argument("config", help="a TOML/JSON config giving the domain and base settings")
    add_config_arguments(parser.add_argument_group("config"))
    grid = parser.add_argument_group("grid")
    grid.add_argument("--grid", action="append", default=[], metavar="KEY=V1,V2",
                      help="a grid axis over any config key, values read like --set values, e.g. "
                           "--grid surrogate.epochs=50,200 --grid selection.block=[4,3],[8,6]; "
                           "--grid seed=0,1,2 and --grid variant=dsage,map_elites work too")
    grid.add_argument("--seeds", type=int, help="seeds 0..K-1 per grid point (default 5)")
    grid.add_argument("--variants", help="comma-separated variants (default: the paper's comparison, or the "
                                         "config's variant when --grid names other keys)")
    output = parser.add_argument_group("output")
    output.add_argument("--out", default="tb_logs", help="storage folder or URI (default %(default)s; s3://, gs://, "
                                                         "file://); the experiment is <out>/<name> (<name> being "
                                                         "the config's name key), one folder per trial in it")
    output.add_argument("--api", choices=["tuner", "run"], default="tuner", help="tune.Tuner (default) or tune.run")
    add_ray_arguments(parser, local=False, resume="continue the interrupted experiment <out>/<name>")
    parser.set_defaults(handler=_ablate)


def _add_config(subparsers) -> None:
    parser = subparsers.add_parser(
        "config", help="list every config key (one line each: name, default, values, status, note); with a config "
                       "file, print the config a run resolves it to, as JSON (runs nothing)")
    parser.add_argument("config", nargs="?", help="a TOML/JSON config, e.g. experiments/configs/maze_dsage.toml "
                                                  "(without one: the list of keys)")
    listing = parser.add_argument_group("the list of keys")
    listing.add_argument("--domain", help="also list this domain's section (maze, mario, gym, ...)")
    listing.add_argument("--experimental", action="store_true", help="also list the experimental keys")
    add_config_arguments(parser)
    parser.set_defaults(handler=_config)


def _config(args: argparse.Namespace) -> int:
    import json

    if args.config is None:
        from dsage_ray.config_listing import format_lines, key_lines
        from dsage_ray.domains import domain_names
        from dsage_ray.errors import InputError, did_you_mean

        if args.domain is not None and args.domain not in domain_names():
            raise InputError(f"--domain: unknown domain {args.domain!r} (known: {', '.join(domain_names())})"
                             f"{did_you_mean(args.domain, domain_names())}")
        print(format_lines(key_lines(domain=args.domain, experimental=args.experimental)))
        return 0
    # Defaults, preset, variant and --set resolved exactly as `run` resolves them; nothing else is imported.
    flat = load_run_config(args, args.config).to_flat()
    # One key per line (lists inline): valid JSON that also greps and diffs well.
    print("{\n" + ",\n".join(f"  {json.dumps(key)}: {json.dumps(flat[key])}" for key in sorted(flat)) + "\n}")
    return 0


def _run(args: argparse.Namespace) -> int:
    from dsage_ray.core.tensorboard_log import tensorboard_hint
    from dsage_ray.runs import run

    # The file and the options, not a config built from them: a resume keeps what they do not say.
    result = run(args.config, preset=args.preset, overrides=config_overrides(args), local=args.local, out=args.out,
                 workers=args.workers, address=args.address, resume=args.resume)
    # Last, so that it is what the terminal shows when the run ends.
    print(f"run folder: {result.path}\nopen it in TensorBoard: {tensorboard_hint(result.path)}")
    return 0


def _ablate(args: argparse.Namespace) -> int:
    from dsage_ray.core.tensorboard_log import tensorboard_hint
    from dsage_ray.runs import ablate

    # As for run: the file and the options, so that a resume compares only what they say.
    experiment = ablate(args.config, preset=args.preset, overrides=config_overrides(args), grid=args.grid,
                        seeds=args.seeds,
                        variants=args.variants.split(",") if args.variants else None, out=args.out,
                        workers=args.workers, address=args.address, resume=args.resume, api=args.api)
    print(f"experiment folder: {experiment.path}\nsummarise it with: python experiments/summarize.py "
          f"{experiment.path}\nopen it in TensorBoard: {tensorboard_hint(experiment.path)}")
    return 0


def main(argv: list[str] | None = None) -> int:
    """Runs one command; every error it reports ends it with one line and the exit code of its kind.

    The line is ``dsage-ray <command>: error: <message>`` on stderr; the codes are those of
    :mod:`dsage_ray.errors` (2 bad input, 3 resources, 4 a failed trial, 5 unfinished trials,
    1 another reported failure, 130 Ctrl+C). Any other exception is a bug and keeps its traceback.
    """
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.handler(args) or 0)
    except BrokenPipeError:
        # The reader went away (`dsage-ray config … | head`): not an error of ours. Point stdout at
        # devnull so the interpreter's final flush does not raise again.
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    except (DsageError, ValueError, OSError, RuntimeError, KeyboardInterrupt) as exc:
        code, message = describe(exc)
        if isinstance(exc, (KeyboardInterrupt, Interrupted)):
            message += resume_hint(args, sys.argv[1:] if argv is None else argv)
        print(f"{command_name(args)}: error: {message}", file=sys.stderr)
        return code


def resume_hint(args: argparse.Namespace, argv: list[str]) -> str:
    """``"; continue with: dsage-ray … --out FOLDER --resume"`` for a command that can continue, else ``""``.

    The folder is named even when the user did not give one (a default with a time stamp cannot be retyped).
    """
    if not hasattr(args, "resume") or getattr(args, "collect_only", False):
        return ""
    words = list(argv)
    if getattr(args, "out", None) is not None and not any(w == "--out" or w.startswith("--out=") for w in words):
        words += ["--out", str(args.out)]
    if "--resume" not in words:
        words.append("--resume")
    return f"; continue with: {shlex.join(['dsage-ray', *words])}"


def command_name(args: argparse.Namespace) -> str:
    """``dsage-ray run``, ``dsage-ray maze eval``, ...: the command as the user typed it."""
    return " ".join(["dsage-ray", args.command, getattr(args, f"{args.command}_command", None) or ""]).strip()


if __name__ == "__main__":
    sys.exit(main())
