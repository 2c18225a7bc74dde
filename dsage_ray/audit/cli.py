"""``dsage-ray audit`` and ``dsage-ray compare``."""

from __future__ import annotations

import argparse
import re
import time
from pathlib import Path

#: The agent audited when ``--agent`` is not given: the PPO agent shipped with the package.
DEFAULT_AGENT = "rllib:ppo_maze"


def add_subparser(subparsers) -> None:
    """Registers ``audit`` and ``compare`` on the top-level CLI's sub-parsers."""
    from dsage_ray.cli import add_config_arguments

    audit = subparsers.add_parser(
        "audit", help="search for mazes where an agent fails and save them as a collection",
        description="Runs DSAGE with a failure-eliciting objective on valid mazes (through Ray Tune unless "
                    "--local), then re-evaluates every elite with a recorded seed and writes collection.json, "
                    "layout files, PNGs, the heatmap and report.html.")
    audit.add_argument("--agent", default=DEFAULT_AGENT, metavar="SPEC",
                       help=f"agent spec (default {DEFAULT_AGENT}): rllib:PATH, dcd:PATH, builtin:..., torchscript:PATH")
    add_config_arguments(audit)
    audit.set_defaults(preset="cpu")
    audit.add_argument("--budget", type=int, help="real evaluations of the search (default: the preset's)")
    audit.add_argument("--objective", default="failure_rate", choices=("failure_rate", "regret"),
                       help="what the search maximises on valid levels (default failure_rate)")
    audit.add_argument("--measures", default="num_walls,optimal_path_length",
                       help="comma-separated measures (default num_walls,optimal_path_length; the paper's: "
                            "num_walls,mean_path_length)")
    audit.add_argument("--seed", type=int, default=0, help="run seed (also seeds the collection's re-evaluations)")
    audit.add_argument("--episodes", type=int, help="episodes per re-evaluation in the collection")
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
        description="Evaluates agents A and B on every level of a collection with its recorded seed and reports "
                    "where B is worse (and better) than A, as a table and an HTML page.")
    compare.add_argument("--agent", action="append", required=True, metavar="SPEC",
                         help="give twice: --agent A --agent B")
    compare.add_argument("--collection", required=True, metavar="DIR", help="a collection folder from dsage-ray audit")
    compare.add_argument("--threshold", type=float, default=0.1,
                         help="success-rate difference that counts as worse/better (default 0.1)")
    compare.add_argument("--episodes", type=int, help="override the recorded episodes per level")
    compare.add_argument("--html", help="HTML page to write (default DIR/compare-<A>-vs-<B>.html)")
    compare.set_defaults(handler=run_compare_command)


def _slug(spec: str) -> str:
    return re.sub(r"[^A-Za-z0-9]+", "_", spec.split("?")[0].rstrip("/").split("/")[-1]).strip("_")[:40] or "agent"


def run_audit_command(args: argparse.Namespace) -> int:
    from dsage_ray.agents import AgentError, load_agent
    from dsage_ray.audit.collection import audit_config
    from dsage_ray.audit.run import run_audit
    from dsage_ray.config import parse_override

    try:
        load_agent(args.agent)  # fail in one line now, not inside a Ray actor later
    except (AgentError, OSError) as exc:
        raise SystemExit(f"dsage-ray audit: error: {exc}") from None
    measures = tuple(m.strip() for m in args.measures.split(",") if m.strip())
    config = audit_config(agent=args.agent, preset=args.preset, objective=args.objective, measures=measures,
                          budget=args.budget, seed=args.seed, name=f"audit_{_slug(args.agent)}",
                          overrides=dict(parse_override(item) for item in args.overrides))
    out = Path(args.out) if args.out else Path("tb_logs") / f"audit-{_slug(args.agent)}-{time.strftime('%Y%m%d-%H%M%S')}"
    if args.collect_only and not args.out:
        raise SystemExit("dsage-ray audit: error: --collect-only needs the --out of the search to collect from")
    try:
        collection = run_audit(config, out_dir=out, local=args.local, workers=args.workers, address=args.address,
                               resume=args.resume, episodes=args.episodes, max_levels=args.max_levels,
                               collect_only=args.collect_only)
    except RuntimeError as exc:  # e.g. --collect-only on a folder without a search checkpoint
        raise SystemExit(f"dsage-ray audit: error: {exc}") from None
    from dsage_ray.audit.collection import load_collection

    levels = load_collection(collection)["levels"]
    failing = sum(lv["success_rate"] < 1.0 for lv in levels)
    never = sum(lv["success_rate"] == 0.0 for lv in levels)
    print(f"collection: {collection} ({len(levels)} levels, {failing} with failures, {never} never solved)")
    for lv in levels[:5]:
        print(f"  #{lv['id']:<4} {args.objective} {lv['objective']:.3f}  success {lv['success_rate']:.2f}  "
              f"mean path {lv['mean_path_length']:.1f} (optimal {lv['optimal_path_length']})  "
              f"{collection / lv['layout_file']}  seed {lv['seed']}")
    print(f"report: {collection / 'report.html'}")
    return 0


def run_compare_command(args: argparse.Namespace) -> int:
    from dsage_ray.agents import AgentError
    from dsage_ray.audit.compare import compare_agents, format_comparison

    if len(args.agent) != 2:
        raise SystemExit(f"dsage-ray compare: error: give exactly two agents (--agent A --agent B), got {len(args.agent)}")
    a, b = args.agent
    html_path = Path(args.html) if args.html else Path(args.collection) / f"compare-{_slug(a)}-vs-{_slug(b)}.html"
    try:
        comparison = compare_agents(a, b, collection_dir=args.collection, threshold=args.threshold,
                                    episodes=args.episodes, html_path=html_path)
    except (AgentError, OSError) as exc:
        raise SystemExit(f"dsage-ray compare: error: {exc}") from None
    print(format_comparison(comparison))
    print(f"\nHTML: {html_path}")
    return 0
