"""Argument pieces every ``dsage-ray`` command module shares (the top-level CLI, ``audit``, the domains').

A leaf module: the command modules import it, and :mod:`dsage_ray.cli` imports the command modules,
so none of them needs to import :mod:`dsage_ray.cli` back.
"""

from __future__ import annotations

import argparse
import re
from collections.abc import Callable
from typing import Any

#: Seconds per unit of a ``--time-budget`` (no unit: seconds).
_DURATION_UNITS = {"": 1.0, "s": 1.0, "m": 60.0, "h": 3600.0}
_DURATION = re.compile(r"(\d+(?:\.\d*)?|\.\d+)\s*([smh]?)")


def add_config_arguments(parser: argparse.ArgumentParser | argparse._ArgumentGroup, *,
                         preset_default: str | None = None) -> None:
    """The config arguments every run-like command shares (on a parser or one of its argument groups).

    ``preset_default``: the preset the command uses without ``--preset``, for its help.
    """
    default = f" (default {preset_default})" if preset_default else ""
    parser.add_argument("--preset", action=LazyHelp, help_text=lambda: preset_help() + default)
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                        help="override a config key, e.g. --set budget=2000 --set surrogate.epochs=50")
    parser.add_argument("--time-budget", type=parse_duration, metavar="DURATION",
                        help="also stop once the run has stepped this long (sets time_budget): 90, 90s, 10m or "
                             "1.5h; the evaluation budget still applies, whichever comes first ends the run")
    parser.add_argument("--search", choices=("fixed", "auto"),
                        help="auto: run DSAGE, and continue with the domain's direct search (the one "
                             "the domain names) on the same archive where the surrogate "
                             "costs more than it buys: with --time-budget, at once if fewer than 3 surrogate "
                             "iterations fit in the time left after the random levels; else at its first picks, "
                             "after playing 8 of them, if a pick costs over 3x a random level, surrogate time "
                             "included. Audits with --time-budget search with auto unless told, but in a domain "
                             "whose audits keep DSAGE (they say why). The choice and why are printed. The same as "
                             "--set search=...")
    parser.add_argument("--surrogate-init", metavar="PATH",
                        help="warm-start the surrogate (sets surrogate.init): a file of `dsage-ray surrogate "
                             "pretrain`, or an earlier run or audit folder of the same network and encoding")


def parse_duration(text: str) -> float:
    """``"90"``, ``"90s"``, ``"10m"``, ``"1.5h"`` → seconds (``--time-budget``'s argparse type).

    Raises:
        argparse.ArgumentTypeError: Not a non-negative number with an optional ``s``/``m``/``h`` unit;
            argparse prefixes the flag's name to the message.
    """
    match = _DURATION.fullmatch(text.strip().lower())
    if match is None:
        raise argparse.ArgumentTypeError(f"expected seconds or a duration such as 90s, 10m or 1.5h, got {text!r}")
    return float(match[1]) * _DURATION_UNITS[match[2]]


def config_overrides(args: argparse.Namespace) -> dict:
    """The dotted config keys that ``--set``, ``--search``, ``--time-budget`` and ``--surrogate-init`` give (not
    ``--preset``)."""
    from dsage_ray.config import ConfigError, parse_override

    overrides = dict(parse_override(item) for item in args.overrides)
    if args.search is not None:
        if overrides.setdefault("search", args.search) != args.search:
            raise ConfigError(f"--search {args.search} and --set search={overrides['search']} disagree: give one")
    if args.time_budget is not None:
        overrides["time_budget"] = args.time_budget
    if args.surrogate_init is not None:
        overrides["surrogate.init"] = args.surrogate_init
    return overrides


def load_run_config(args: argparse.Namespace, path: str | None):
    """The :class:`~dsage_ray.config.RunConfig` of ``path`` (or the defaults) with ``--preset`` and
    :func:`config_overrides` applied."""
    from dsage_ray.config import RunConfig

    overrides = config_overrides(args)
    if args.preset:
        overrides["preset"] = args.preset
    return RunConfig.from_file(path, overrides) if path else RunConfig.build(overrides)


def add_ray_arguments(parser: argparse.ArgumentParser, *, resume: str | None, local: bool = True) -> None:
    """Where a search runs (``--local``, ``--workers``, ``--address``) and ``--resume``: one definition,
    one help group, for every command that searches (``run``, ``ablate``, ``audit``).

    Args:
        parser: The command's parser.
        resume: What ``--resume`` continues, for its help; None: no ``--resume`` (a command that always
            continues, such as ``audit-series``).
        local: Offer ``--local`` (``ablate`` runs through Tune only).
    """
    group = parser.add_argument_group("where it runs")
    if local:
        group.add_argument("--local", action="store_true", help="run in this process, without Ray")
    group.add_argument("--workers", type=int,
                       help="simulator actors per run (sets ray.num_workers; 0: simulate in the trial process)")
    group.add_argument("--address", help="join an existing Ray cluster (default: RAY_ADDRESS, else a new local one)")
    if resume is not None:
        group.add_argument("--resume", action="store_true", help=resume)


class LazyHelp(argparse.Action):
    """A store action (``append=True``: an append action) whose help ``help_text()`` builds when help is shown.

    Some help texts list every domain's presets or agent kinds, which imports every domain: about a
    second that no command but ``--help`` needs.
    """

    def __init__(self, option_strings: list[str], dest: str, *, help_text: Callable[[], str],
                 append: bool = False, **kwargs: Any) -> None:
        self._help_text = help_text
        self._append = append
        super().__init__(option_strings, dest, **kwargs)

    @property
    def help(self) -> str:
        return self._help_text()

    @help.setter
    def help(self, _value: str | None) -> None:
        pass  # argparse.Action.__init__ assigns it; the property above is the help

    def __call__(self, parser, namespace, values, option_string=None) -> None:
        if self._append:
            values = [*(getattr(namespace, self.dest, None) or []), values]
        setattr(namespace, self.dest, values)


class LazyTextFormatter(argparse.RawDescriptionHelpFormatter):
    """:class:`argparse.RawDescriptionHelpFormatter` that also takes a description, an epilog or an argument
    group's description as a function, called when help is shown (what :class:`LazyHelp` is for an option)."""

    def add_text(self, text: str | Callable[[], str] | None) -> None:
        super().add_text(text() if callable(text) else text)


def preset_budgets(domain: str) -> dict[str, int]:
    """The real evaluations of each preset of ``domain``, in its registration's order."""
    from dsage_ray.config import RunConfig, presets

    return {name: RunConfig.build(domain=domain, preset=name).budget for name in presets(domain)}


def preset_help() -> str:
    """``--preset``'s help, from the domain registrations: every domain's presets and their evaluations."""
    from dsage_ray.domains import domain_names
    from dsage_ray.errors import DsageError

    listed = []
    for domain in domain_names():
        try:
            budgets = preset_budgets(domain)
        except DsageError:
            continue  # a plug-in that does not load has no presets to offer
        listed.append(f"{domain}: " + ", ".join(f"{name} {budget:,}" for name, budget in budgets.items()))
    return "preset of the domain; evaluations per preset: " + "; ".join(listed)
