"""``dsage-ray surrogate``: pretrain a surrogate once, warm-start many runs and audits with it.

* ``pretrain`` trains a fresh surrogate on every level of earlier runs or audits (``--from``), or first
  runs an audit search of ``--levels`` evaluations of ``--agent`` and trains on those;
* ``info`` prints what a pretrained file or a run holds (levels, agent, network, held-out accuracy).

``--surrogate-init FILE`` (``run``, ``audit``, ``ablate``) then warm-starts from the file.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from dsage_ray.domains.registry import DEFAULT_DOMAIN
from dsage_ray.errors import InputError

EXAMPLES = """\
examples:
  dsage-ray surrogate pretrain --agent dcd:accel --levels 2000 --out tb_logs/accel.surrogate --local
  dsage-ray surrogate pretrain --from tb_logs/audit-dcd_accel-20261125-0900 --out tb_logs/accel.surrogate
  dsage-ray audit --agent dcd:accel --surrogate-init tb_logs/accel.surrogate --budget 500
  dsage-ray surrogate info tb_logs/accel.surrogate
"""


def add_subparser(subparsers) -> None:
    from dsage_ray.cli_args import LazyHelp, add_config_arguments, add_ray_arguments
    from dsage_ray.domains.agent_help import agent_kinds_help

    parser = subparsers.add_parser(
        "surrogate", help="pretrain a surrogate and inspect pretrained ones (warm starts, beyond the paper)",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Warm starts: a surrogate trained on earlier evaluations of an agent starts a run or audit "
                    "(--surrogate-init), so the search exploits from its first outer iteration.",
        epilog=EXAMPLES)
    commands = parser.add_subparsers(dest="surrogate_command", required=True)
    pretrain = commands.add_parser(
        "pretrain", help="train a surrogate on earlier runs (--from) or on a new audit search (--agent --levels)",
        formatter_class=argparse.RawDescriptionHelpFormatter, epilog=EXAMPLES,
        description="Trains a fresh surrogate on every level of its sources (not only the most recent "
                    "train_window) and saves it; 10% of the levels are held out to report its accuracy, then "
                    "trained on too.")
    source = pretrain.add_argument_group("what it trains on (one of)")
    source.add_argument("--from", dest="sources", nargs="+", metavar="PATH",
                        help="earlier surrogate runs, audits or pretrained files; their levels are pooled")
    source.add_argument("--agent", metavar="SPEC", action=LazyHelp,
                        help_text=lambda: f"run an audit search of this agent first: its spec, of a kind --domain "
                                          f"plays ({agent_kinds_help()})")
    source.add_argument("--levels", type=int, help="with --agent: real evaluations of that search")
    source.add_argument("--domain", default=DEFAULT_DOMAIN, help="with --agent: the domain (default maze)")
    source.add_argument("--seed", type=int, default=0, help="the search's and the training's seed (default 0)")
    config = pretrain.add_argument_group("the network and its training")
    add_config_arguments(config)
    config.add_argument("--epochs", type=int, help="epochs over all levels (default: the config's surrogate.epochs)")
    output = pretrain.add_argument_group("output")
    output.add_argument("--out", required=True, help="the pretrained file to write")
    output.add_argument("--search-out", metavar="DIR",
                        help="with --agent: the search's --out, as run's --out (default: beside --out, named "
                             "after it with _search for its suffix: tb_logs/accel_search for --out "
                             "tb_logs/accel.surrogate)")
    add_ray_arguments(pretrain, resume="with --agent: continue the interrupted search in --search-out")
    pretrain.set_defaults(handler=pretrain_command)

    info = commands.add_parser("info", help="what a pretrained file or a surrogate run holds")
    info.add_argument("path", help="a pretrained file, a run or audit folder, or a checkpoint.dsage")
    info.set_defaults(handler=info_command)


def pretrain_command(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    from dsage_ray.cli_args import config_overrides
    from dsage_ray.core.warm_start import pretrain_surrogate

    if bool(args.sources) == bool(args.agent):
        raise InputError("give either --from PATH ... (earlier runs) or --agent SPEC --levels N (a new search)")
    if args.agent and (args.levels is None or args.levels < 1):
        raise InputError("--agent needs --levels N (N >= 1): the real evaluations of its search")
    if args.epochs is not None and args.epochs < 1:
        raise InputError(f"--epochs must be positive, got {args.epochs}")
    out = Path(args.out)
    if out.is_dir():
        raise InputError(f"--out {out} is a folder; name the file to write")
    overrides = config_overrides(args)
    if overrides.pop("surrogate.init", None):
        raise InputError("--surrogate-init: pretraining starts from fresh weights; pass earlier runs with --from")
    if args.sources:
        if args.preset:
            raise InputError("--preset applies to the search of --agent; with --from, change keys with --set")
        sources, overrides = args.sources, overrides
    else:
        sources, overrides = [_search(args, overrides, out)], {}
    bars: list[tqdm] = []  # opened at the first epoch: a source that does not load ends with its error alone

    def advance(epoch: int, total: int) -> None:
        if not bars:
            bars.append(tqdm(desc="pretrain", unit="epoch", total=total))
        bars[0].update(1)

    try:
        result = pretrain_surrogate(sources, out=out, overrides=overrides, seed=args.seed, epochs=args.epochs,
                                    progress=advance)
    finally:
        for bar in bars:
            bar.close()
    print(describe(result))
    agent = f"--agent {result.agent} " if result.agent else ""
    print(f"pretrained surrogate: {result.path}\nuse it: dsage-ray audit {agent}--surrogate-init {result.path}")
    return 0


def _search(args: argparse.Namespace, overrides: dict, out: Path) -> Path:
    """Runs the audit search that ``--agent --levels`` asks for; returns its folder."""
    from dsage_ray.audit.collection import audit_config
    from dsage_ray.audit.run import default_preset
    from dsage_ray.preflight import preflight
    from dsage_ray.runs import run

    config = audit_config(domain=args.domain, agent=args.agent, preset=args.preset or default_preset(
        args.domain, agent=args.agent), budget=args.levels, seed=args.seed, overrides=overrides)
    search_out = Path(args.search_out) if args.search_out else default_search_out(out)
    if search_out.exists() and not args.resume:
        raise InputError(f"{search_out} already exists: pass --resume to continue its search, or another "
                         f"--search-out")
    preflight(config)
    result = run(config, local=args.local, out=search_out, workers=args.workers, address=args.address,
                 resume=args.resume)
    return result.path


def default_search_out(out: Path) -> Path:
    """Where ``pretrain --agent`` runs its search without ``--search-out``: beside ``out``, ``_search`` for its
    suffix."""
    return out.with_name(out.stem + "_search")


def describe(source) -> str:
    """A few lines on what a warm start holds."""
    config = source.config.surrogate
    lines = [f"{source.path}: a {source.config.domain} {config.kind} surrogate, channels {config.channels}; "
             f"{source.levels} levels"
             + (f" of {source.agent}" if source.agent else "")]
    info = dict(source.info)
    if info:
        rho = ", ".join(f"{name} {value:.3f}" for name, value in info.get("held_out_spearman", {}).items())
        lines.append(f"pretrained: {info['epochs']} epochs in {info['seconds']:.0f} s"
                     + (f"; held-out Spearman ρ ({info['held_out']} levels): {rho}" if rho else ""))
    return "\n".join(lines)


def info_command(args: argparse.Namespace) -> int:
    from dsage_ray.core.warm_start import load_warm_start

    print(describe(load_warm_start(args.path)))
    return 0
