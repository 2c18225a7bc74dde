"""``dsage-ray audit`` and ``dsage-ray compare``: they parse, call the library and print."""

from __future__ import annotations

import argparse

from dsage_ray.errors import InputError

AUDIT_EXAMPLES = """\
examples:
  dsage-ray audit                                         # a demo: the shipped PPO agent, --preset demo
  dsage-ray audit --agent dcd:path/to/agent.tar --out tb_logs/audit_mine     # your agent (cpu preset)
  dsage-ray audit --agent builtin:random --preset tiny --local               # a smoke test, no Ray
  dsage-ray audit --agent rllib:path/to/new --reference rllib:path/to/old    # where new is worse than old
  dsage-ray audit --domain mario --agent astar --preset tiny
  dsage-ray compare --agent rllib:ppo_maze --agent builtin:wall_follower --collection tb_logs/audit_mine/collection
  dsage-ray compare --agent astar --agent astar:200 --collection tb_logs/audit_mario/collection
  dsage-ray audit --agent dcd:accel --out tb_logs/audit_accel --resume        # after Ctrl+C

Without --agent the audit is a short demo on the domain's shipped agent (Maze: rllib:ppo_maze) with the
domain's demo preset, and says so; a named agent gets the cpu preset (Maze: 2,000 evaluations).
Python: dsage_ray.run_audit() takes the same arguments and returns the collection (docs/API.md).
"""


def add_subparser(subparsers) -> None:
    """Registers ``audit`` and ``compare`` on the top-level CLI's sub-parsers."""
    from dsage_ray.cli_args import add_config_arguments, add_ray_arguments

    audit = subparsers.add_parser(
        "audit", help="search for levels where an agent fails (or does worse than a reference) and save them",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Runs DSAGE with a failure-eliciting objective on valid levels (through Ray Tune unless "
                    "--local),\nthen re-evaluates every elite with a recorded seed and writes collection.json, "
                    "level files,\nPNGs, the heatmap and report.html.",
        epilog=AUDIT_EXAMPLES)
    what = audit.add_argument_group("what to audit")
    what.add_argument("--domain", default="maze",
                      help="maze (default), mario, or a plug-in domain that declares audits")
    what.add_argument("--agent", metavar="SPEC",
                      help=f"agent spec, of a kind the domain plays ({agent_help()}). Without it: a demo audit "
                           f"of the domain's shipped agent (maze: rllib:ppo_maze) with the demo preset")
    what.add_argument("--reference", metavar="SPEC",
                      help="maze: search where --agent does worse than this agent, on the same seeds "
                           "(objective regression)")
    search = audit.add_argument_group("the search")
    add_config_arguments(search)
    search.add_argument("--variant", default="dsage",
                        help="dsage (default) or another variant of the domain, e.g. map_elites or dr "
                             "(experiments/audit_comparison.py compares them)")
    search.add_argument("--budget", type=int, help="real evaluations of the search (default: the preset's)")
    search.add_argument("--objective",
                        help="what the search maximises on valid levels. maze: failure_rate (default), regret, "
                             "regression (the default with --reference); mario: incompletion (1 - completion)")
    search.add_argument("--measures",
                        help="comma-separated measures. maze default num_walls,optimal_path_length (the paper's: "
                             "num_walls,mean_path_length); mario default the paper's sky_tiles,mean_jumps")
    search.add_argument("--seed", type=int, default=0, help="run seed (also seeds the collection's re-evaluations)")
    collection = audit.add_argument_group("the collection")
    collection.add_argument("--episodes", type=int, help="episodes (mario: runs) per re-evaluation in the collection")
    collection.add_argument("--max-levels", type=int, help="keep only the N worst elites in the collection")
    collection.add_argument("--out", help="audit folder (default tb_logs/audit-<agent>-<time>)")
    collection.add_argument("--collect-only", action="store_true",
                            help="skip the search: build the collection from the last checkpoint of the search "
                                 "in --out")
    add_ray_arguments(audit, resume="continue the interrupted search in --out")
    audit.set_defaults(handler=run_audit_command)

    compare = subparsers.add_parser(
        "compare", help="re-evaluate two agents on a saved collection with the same seeds",
        description="Evaluates agents A and B on every level of a collection (of any domain that declares audits) "
                    "with its recorded seed and reports where B is worse (and better) than A, as a table and an "
                    "HTML page.")
    compare.add_argument("--agent", action="append", required=True, metavar="SPEC",
                         help=f"give twice: --agent A --agent B; kinds the collection's domain plays ({agent_help()})")
    compare.add_argument("--collection", required=True, metavar="DIR", help="a collection folder from dsage-ray audit")
    compare.add_argument("--threshold", type=float, default=0.1,
                         help="success-rate difference that counts as worse/better (default 0.1)")
    compare.add_argument("--episodes", type=int, help="override the recorded episodes per level")
    compare.add_argument("--workers", type=int,
                         help="evaluate on N Ray simulator actors (default: in this process)")
    compare.add_argument("--html", help="HTML page to write (default DIR/compare-<A>-vs-<B>.html)")
    compare.set_defaults(handler=run_compare_command)


def agent_help() -> str:
    """The agent spec forms of each domain, for help texts: ``maze: builtin:NAME, ...; mario: astar[:ITERATIONS]``."""
    from dsage_ray.domains import agent_forms

    return "; ".join(f"{domain}: {', '.join(forms)}" for domain, forms in agent_forms().items())


def run_audit_command(args: argparse.Namespace) -> int:
    """Handler of ``dsage-ray audit``: :func:`dsage_ray.run_audit`, then what it found.

    Errors end the command through :func:`dsage_ray.cli.main` (one line, the exit code of their kind).
    """
    from dsage_ray.audit.run import run_audit
    from dsage_ray.cli_args import config_overrides

    if args.agent is None:
        print(_demo_notice(args), flush=True)
    measures = tuple(m.strip() for m in args.measures.split(",") if m.strip()) if args.measures else None
    collection = run_audit(
        agent=args.agent, domain=args.domain, reference=args.reference, preset=args.preset, variant=args.variant,
        objective=args.objective, measures=measures, budget=args.budget, seed=args.seed,
        overrides=config_overrides(args), out=args.out, local=args.local,
        workers=args.workers, address=args.address, resume=args.resume, episodes=args.episodes,
        max_levels=args.max_levels, collect_only=args.collect_only)
    print(f"collection: {collection.path}")
    print(collection.summary_line)
    for level in collection.levels[:5]:
        if level.regression is not None:
            numbers = (f"success {level.success_rate:.2f}  reference {level.fields['reference']['success_rate']:.2f}  "
                       f"regression {level.regression:+.2f}")
        else:
            numbers = f"{collection.objective} {level.objective:.3f}  success {level.success_rate:.2f}"
        print(f"  #{level.id:<4} {numbers}  {level.level_path}  seed {level.seed}")
    if collection.levels:
        print(f"reproduce #0: {collection.levels[0].reproduce}")
    if collection.search_dir is not None:
        from dsage_ray.core.tensorboard_log import tensorboard_hint

        print(f"search in TensorBoard: {tensorboard_hint(collection.search_dir)}")
    print(f"report: {collection.report_path}")
    return 0


def _demo_notice(args: argparse.Namespace) -> str:
    """The one line saying what ``dsage-ray audit`` without ``--agent`` audits, and how long it is."""
    from dsage_ray.audit.collection import audit_spec
    from dsage_ray.audit.run import default_preset
    from dsage_ray.cli_args import preset_budgets

    agent = audit_spec(args.domain).audit.default_agent
    preset = args.preset or default_preset(args.domain, agent=None)
    budget = args.budget or preset_budgets(args.domain).get(preset)  # an unknown preset is reported next
    length = f" ({budget:,} evaluations)" if budget else ""
    return f"no --agent: auditing the shipped demo agent {agent} with --preset {preset}{length}; name yours with --agent SPEC"


def run_compare_command(args: argparse.Namespace) -> int:
    """Handler of ``dsage-ray compare``."""
    from pathlib import Path

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
