"""``dsage-ray``: the command-line interface (thin: it parses, then calls the library)."""

from __future__ import annotations

import argparse
import importlib
import os
import sys
from pathlib import Path

from dsage_ray.cli_args import add_config_arguments, load_run_config
from dsage_ray.errors import DsageError, describe


def command_modules() -> list[str]:
    """Modules that register sub-commands (each exposes ``add_subparser(subparsers)``): every domain's
    ``cli`` from its registration (``dsage-ray maze ...``), then the audit's."""
    from dsage_ray.domains import domain_names, get_domain

    modules = []
    for name in domain_names():
        try:
            spec = get_domain(name)
        except DsageError:
            continue  # a plug-in that does not load has no sub-command; naming its domain says why
        if spec.cli:
            modules.append(spec.cli)
    return [*modules, "dsage_ray.audit.cli"]


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="dsage-ray", description="DSAGE on Ray: search for diverse levels where an agent fails.")
    subparsers = parser.add_subparsers(dest="command", required=True)
    _add_run(subparsers)
    _add_ablate(subparsers)
    _add_config(subparsers)
    for module_name in command_modules():
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
    parser = subparsers.add_parser("run", help="run DSAGE (or a baseline) from a config file")
    parser.add_argument("config", help="a TOML/JSON config, e.g. experiments/configs/maze_dsage.toml")
    add_config_arguments(parser)
    parser.add_argument("--out", help="output folder (default: tb_logs/<name>; Tune keeps one folder per trial in it)")
    parser.add_argument("--resume", action="store_true", help="continue the run in --out from its last checkpoint")
    parser.add_argument("--local", action="store_true", help="run in this process, without Ray")
    parser.add_argument("--workers", type=int, help="simulator actors (sets ray.num_workers)")
    parser.add_argument("--address", help="join an existing Ray cluster (default: RAY_ADDRESS or a local one)")
    parser.set_defaults(handler=_run)


def _add_ablate(subparsers) -> None:
    parser = subparsers.add_parser("ablate", help="run a grid (the paper's variant x seed, or any config keys) "
                                                  "as one Tune experiment")
    parser.add_argument("config", help="a TOML/JSON config giving the domain and base settings")
    add_config_arguments(parser)
    parser.add_argument("--grid", action="append", default=[], metavar="KEY=V1,V2",
                        help="a grid axis over any config key, values read like --set values, e.g. "
                             "--grid surrogate.epochs=50,200 --grid selection.block=[4,3],[8,6]; "
                             "--grid seed=0,1,2 and --grid variant=dsage,map_elites work too")
    parser.add_argument("--seeds", type=int, help="seeds 0..K-1 per grid point (default 5)")
    parser.add_argument("--variants", help="comma-separated variants (default: the paper's comparison, or the "
                                           "config's variant when --grid names other keys)")
    parser.add_argument("--api", choices=["tuner", "run"], default="tuner", help="tune.Tuner or tune.run")
    parser.add_argument("--out", default="tb_logs", help="storage folder (default tb_logs)")
    parser.add_argument("--resume", action="store_true", help="continue an interrupted experiment")
    parser.add_argument("--workers", type=int, help="simulator actors per trial")
    parser.add_argument("--address", help="join an existing Ray cluster")
    parser.set_defaults(handler=_ablate)


def _add_config(subparsers) -> None:
    parser = subparsers.add_parser("config", help="print the resolved run config as JSON (runs nothing)")
    parser.add_argument("config", help="a TOML/JSON config, e.g. experiments/configs/maze_dsage.toml")
    add_config_arguments(parser)
    parser.set_defaults(handler=_config)


def _config(args: argparse.Namespace) -> int:
    import json

    # Defaults, preset, variant and --set resolved exactly as `run` resolves them; nothing else is imported.
    flat = load_run_config(args, args.config).to_flat()
    # One key per line (lists inline): valid JSON that also greps and diffs well.
    print("{\n" + ",\n".join(f"  {json.dumps(key)}: {json.dumps(flat[key])}" for key in sorted(flat)) + "\n}")
    return 0


def _run(args: argparse.Namespace) -> int:
    config = load_run_config(args, args.config)
    if args.local:
        from dsage_ray.core.loop import run_locally

        out = Path(args.out) if args.out else Path("tb_logs") / config.name
        run_dir = run_locally(config, out_dir=out, resume=args.resume)
    else:
        from dsage_ray.ray.cli import run_with_tune

        run_dir = run_with_tune(config, workers=args.workers, address=args.address, resume=args.resume,
                                out_dir=Path(args.out or "tb_logs").resolve())
    from dsage_ray.core.tensorboard_log import tensorboard_hint

    # Last, so that it is what the terminal shows when the run ends.
    print(f"run folder: {run_dir}\nopen it in TensorBoard: {tensorboard_hint(run_dir)}")
    return 0


def _ablate(args: argparse.Namespace) -> int:
    from dsage_ray.ray.cli import ablate

    config = load_run_config(args, args.config)
    variants = args.variants.split(",") if args.variants else None
    folder = ablate(config, grid=args.grid, seeds=args.seeds, variants=variants, workers=args.workers,
                    address=args.address, resume=args.resume, out_dir=Path(args.out).resolve(), api=args.api)
    from dsage_ray.core.tensorboard_log import tensorboard_hint

    print(f"experiment folder: {folder}\nsummarise it with: python experiments/summarize.py {folder}\n"
          f"open it in TensorBoard: {tensorboard_hint(folder)}")
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
        print(f"{command_name(args)}: error: {message}", file=sys.stderr)
        return code


def command_name(args: argparse.Namespace) -> str:
    """``dsage-ray run``, ``dsage-ray maze eval``, ...: the command as the user typed it."""
    return " ".join(["dsage-ray", args.command, getattr(args, f"{args.command}_command", None) or ""]).strip()


if __name__ == "__main__":
    sys.exit(main())
