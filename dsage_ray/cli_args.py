"""Argument pieces every ``dsage-ray`` command module shares (the top-level CLI, ``audit``, the domains').

A leaf module: the command modules import it, and :mod:`dsage_ray.cli` imports the command modules,
so none of them needs to import :mod:`dsage_ray.cli` back.
"""

from __future__ import annotations

import argparse


def add_config_arguments(parser: argparse.ArgumentParser) -> None:
    """The config arguments every run-like command shares."""
    parser.add_argument("--preset", help="preset of the domain (paper, cpu, tiny, ...)")
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                        help="override a config key, e.g. --set budget=2000 --set surrogate.epochs=50")


def load_run_config(args: argparse.Namespace, path: str | None):
    """The :class:`~dsage_ray.config.RunConfig` of ``path`` (or the defaults) with ``--preset`` and ``--set`` applied."""
    from dsage_ray.config import RunConfig, parse_override

    overrides = dict(parse_override(item) for item in args.overrides)
    if args.preset:
        overrides["preset"] = args.preset
    return RunConfig.from_file(path, overrides) if path else RunConfig.build(overrides)
