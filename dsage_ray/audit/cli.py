"""``dsage-ray audit`` and ``dsage-ray compare``."""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from dsage_ray.errors import InputError


def add_subparser(subparsers) -> None:
    """Registers ``audit`` and ``compare`` on the top-level CLI's sub-parsers."""
    from dsage_ray.cli_args import add_config_arguments

    audit = subparsers.add_parser(
        "audit", help="search for levels where an agent fails (or does worse than a reference) and save them",
        description="Runs DSAGE with a failure-eliciting objective on valid levels (through Ray Tune unless "
                    "--local), then re-evaluates every elite with a recorded seed and writes collection.json, "
                    "level files, PNGs, the heatmap and report.html.")
    audit.add_argument("--domain", default="maze", help="maze (default), mario, or a plug-in domain that declares audits")
    audit.add_argument("--agent", metavar="SPEC",
                       help="agent spec. maze (default rllib:ppo_maze): rllib:PATH, dcd:PATH, builtin:..., "
                            "torchscript:PATH; mario (default astar): astar or astar:ITERATIONS")
    audit.add_argument("--reference", metavar="SPEC",
                       help="maze: search where --agent does worse than this agent, on the same seeds "
                            "(objective regression)")
    add_config_arguments(audit)
    audit.set_defaults(preset="cpu")
    audit.add_argument("--variant", default="dsage",
                       help="the search: dsage (default) or another variant of the domain, e.g. map_elites or dr "
                            "(experiments/audit_comparison.py compares them)")
    audit.add_argument("--budget", type=int, help="real evaluations of the search (default: the preset's)")
    audit.add_argument("--objective",
                       help="what the search maximises on valid levels. maze: failure_rate (default), regret, "
                            "regression (the default with --reference); mario: incompletion (1 - completion)")
    audit.add_argument("--measures",
                       help="comma-separated measures. maze default num_walls,optimal_path_length (the paper's: "
                            "num_walls,mean_path_length); mario default the paper's sky_tiles,mean_jumps")
    audit.add_argument("--seed", type=int, default=0, help="run seed (also seeds the collection's re-evaluations)")
    audit.add_argument("--episodes", type=int, help="episodes (mario: runs) per re-evaluation in the collection")
    audit.add_argument("--max-levels", type=int, help="keep only the N worst elites in the collection")
    audit.add_argument("--out", help="audit folder (default tb_logs/audit-<agent>-<time>)")
    audit.add_argument("--local", action="store_true", help="run in this process, without Ray")
    audit.add_argument("--workers", type=int, help="simulator actors (sets ray.num_workers)")
    audit.add_argument("--address", help="join an existing Ray cluster")
    audit.add_argument("--resume", action="store_true", help="continue an interrupted search in --out")
    audit.add_argument("--collect-only", action="store_true",
                       help="skip the search: build the collection from the last checkpoint of the search in --out")
    audit.set_defaults(handler=run_audit_command)

    compare = subparsers.add_parser(
        "compare", help="re-evaluate two agents on a saved collection with the same seeds",
        description="Evaluates agents A and B on every level of a Maze collection with its recorded seed and "
                    "reports where B is worse (and better) than A, as a table and an HTML page.")
    compare.add_argument("--agent", action="append", required=True, metavar="SPEC",
                         help="give twice: --agent A --agent B")
    compare.add_argument("--collection", required=True, metavar="DIR", help="a collection folder from dsage-ray audit")
    compare.add_argument("--threshold", type=float, default=0.1,
                         help="success-rate difference that counts as worse/better (default 0.1)")
    compare.add_argument("--episodes", type=int, help="override the recorded episodes per level")
    compare.add_argument("--workers", type=int,
                         help="evaluate on N Ray simulator actors (default: in this process)")
    compare.add_argument("--html", help="HTML page to write (default DIR/compare-<A>-vs-<B>.html)")
    compare.set_defaults(handler=run_compare_command)


def run_audit_command(args: argparse.Namespace) -> int:
    """Handler of ``dsage-ray audit``: every check that needs no Ray runs before the search starts.

    Errors end the command through :func:`dsage_ray.cli.main` (one line, the exit code of their kind).
    """
    from dsage_ray.audit.collection import agent_slug, audit_config, audit_spec
    from dsage_ray.audit.collection_file import load_collection
    from dsage_ray.audit.run import run_audit
    from dsage_ray.config import parse_override

    spec = audit_spec(args.domain)
    if args.collect_only and not args.out:
        raise InputError("--collect-only needs the --out of the search to collect from")
    for flag, value in (("--episodes", args.episodes), ("--max-levels", args.max_levels), ("--budget", args.budget)):
        if value is not None and value < 1:
            raise InputError(f"{flag} must be positive, got {value}")
    if args.workers is not None and args.workers < 0:
        raise InputError(f"--workers must be >= 0 (0: simulate in the trial process), got {args.workers}")
    measures = tuple(m.strip() for m in args.measures.split(",") if m.strip()) if args.measures else None
    config = audit_config(domain=args.domain, agent=args.agent, reference=args.reference, preset=args.preset,
                          variant=args.variant, objective=args.objective, measures=measures, budget=args.budget,
                          seed=args.seed,
                          overrides=dict(parse_override(item) for item in args.overrides))
    agent = args.agent or spec.audit.default_agent
    out = (Path(args.out) if args.out
           else Path("tb_logs") / f"audit-{agent_slug(agent)}-{time.strftime('%Y%m%d-%H%M%S')}")
    collection = run_audit(config, out_dir=out, local=args.local, workers=args.workers, address=args.address,
                           resume=args.resume, episodes=args.episodes, max_levels=args.max_levels,
                           collect_only=args.collect_only)
    c = load_collection(collection)
    print(f"collection: {collection}")
    print(_summary_line(c))
    for lv in c["levels"][:5]:
        if "reference" in lv:
            numbers = (f"success {lv['success_rate']:.2f}  reference {lv['reference']['success_rate']:.2f}  "
                       f"regression {lv['regression']:+.2f}")
        else:
            numbers = f"{c['objective']} {lv['objective']:.3f}  success {lv['success_rate']:.2f}"
        print(f"  #{lv['id']:<4} {numbers}  {collection / lv['level_file']}  seed {lv['seed']}")
    if c["levels"]:
        print(f"reproduce #0: {c['levels'][0]['reproduce']}")
    if c.get("search_dir"):  # local searches write their event files too
        from dsage_ray.core.tensorboard_log import tensorboard_hint

        print(f"search in TensorBoard: {tensorboard_hint(c['search_dir'])}")
    print(f"report: {collection / 'report.html'}")
    return 0


def _summary_line(collection: dict) -> str:
    """The collection's failure-diversity numbers (:mod:`dsage_ray.audit.summary`)."""
    from dsage_ray.audit.summary import failure_summary, format_summary

    return format_summary(failure_summary(collection))


def run_compare_command(args: argparse.Namespace) -> int:
    """Handler of ``dsage-ray compare``."""
    from dsage_ray.audit.collection import agent_slug
    from dsage_ray.audit.compare import compare_agents, format_comparison

    if len(args.agent) != 2:
        raise InputError(f"give exactly two agents (--agent A --agent B), got {len(args.agent)}")
    for flag, value in (("--workers", args.workers), ("--episodes", args.episodes)):
        if value is not None and value < 1:
            raise InputError(f"{flag} must be positive, got {value}")
    a, b = args.agent
    html_path = (Path(args.html) if args.html
                 else Path(args.collection) / f"compare-{agent_slug(a)}-vs-{agent_slug(b)}.html")
    comparison = compare_agents(a, b, collection_dir=args.collection, threshold=args.threshold,
                                episodes=args.episodes, html_path=html_path, workers=args.workers)
    print(format_comparison(comparison))
    print(f"\nHTML: {html_path}")
    return 0
