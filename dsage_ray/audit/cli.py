"""``dsage-ray audit``, ``dsage-ray compare`` and ``dsage-ray audit-series``: they parse, call the library and
print."""

from __future__ import annotations

import argparse
from pathlib import Path

from dsage_ray.domains.registry import DEFAULT_DOMAIN
from dsage_ray.errors import InputError


def add_subparser(subparsers) -> None:
    """Registers ``audit`` and ``compare`` on the top-level CLI's sub-parsers."""
    from dsage_ray.audit import cli_help
    from dsage_ray.cli_args import LazyHelp, LazyTextFormatter, add_config_arguments, add_ray_arguments
    from dsage_ray.domains.agent_help import agent_kinds_help

    # Every domain says its own part of the help (its AuditSpec), read only when help is shown.
    audit = subparsers.add_parser(
        "audit", help="search for levels where an agent fails (or does worse than a reference) and save them",
        formatter_class=LazyTextFormatter,
        description="Runs DSAGE with a failure-eliciting objective on valid levels (through Ray Tune unless "
                    "--local),\nthen re-evaluates every elite with a recorded seed and writes collection.json, "
                    "level files,\nPNGs, the heatmap and report.html.",
        epilog=cli_help.audit_epilog)
    what = audit.add_argument_group("what to audit")
    what.add_argument("--domain", default=DEFAULT_DOMAIN, action=LazyHelp, help_text=cli_help.domain_help)
    what.add_argument("--agent", metavar="SPEC", action=LazyHelp,
                      help_text=lambda: f"agent spec, of a kind the domain plays ({agent_kinds_help()}). Without it: a "
                                        f"demo audit of the domain's shipped agent ({cli_help.demo_agents()}) with "
                                        f"the demo preset")
    what.add_argument("--reference", metavar="SPEC", action=LazyHelp, help_text=cli_help.reference_help)
    add_domain_arguments(audit)
    nominal = audit.add_argument_group("the nominal check", cli_help.nominal_help)
    nominal.add_argument("--expect-return", type=float, metavar="X",
                         help="the agent's mean return on the nominal level (default: its own training record, e.g. "
                              "an RL Zoo folder's evaluations.npz)")
    nominal.add_argument("--allow-failing-nominal", action="store_true",
                         help="go on with the search after a failing nominal check (it is printed and recorded)")
    search = audit.add_argument_group("the search")
    add_config_arguments(search)
    search.add_argument("--variant",
                        help="the search: dsage (default) or another variant of the domain, e.g. map_elites or dr "
                             "(experiments/audit_comparison.py compares them). The same as --set variant=VARIANT; "
                             "both at once must agree")
    search.add_argument("--budget", type=int, help="real evaluations of the search (default: the preset's)")
    search.add_argument("--objective", action=LazyHelp, help_text=cli_help.objective_help)
    search.add_argument("--measures", action=LazyHelp, help_text=cli_help.measures_help)
    search.add_argument("--seed", type=int, default=0, help="run seed (also seeds the collection's re-evaluations)")
    collection = audit.add_argument_group("the collection")
    collection.add_argument("--episodes", type=int, action=LazyHelp,
                            help_text=lambda: cli_help.episodes_help("per re-evaluation in the collection"))
    collection.add_argument("--max-levels", type=int, help="keep only the N worst elites in the collection")
    collection.add_argument("--out", metavar="DIR", action=LazyHelp, help_text=lambda: (
        f"audit folder (default tb_logs/audit-<agent>-<YYYYMMDD-HHMMSS>, <agent> being the spec, or its last path "
        f"part, with _ for other characters than letters and digits: tb_logs/audit-{_slug(cli_help.default_agent())}"
        f"-20260101-093000 for {cli_help.default_agent()}, tb_logs/audit-accel_tar-... for dcd:runs/accel.tar); the "
        f"search goes to DIR/search, the collection and its report to DIR/collection"))
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
    compare.add_argument("--agent", action=LazyHelp, append=True, required=True, metavar="SPEC",
                         help_text=lambda: f"give twice: --agent A --agent B; kinds the collection's domain plays "
                                           f"({agent_kinds_help()})")
    compare.add_argument("--collection", required=True, metavar="DIR", help="a collection folder from dsage-ray audit")
    compare.add_argument("--threshold", type=float, default=0.1,
                         help="success-rate difference that counts as worse/better (default 0.1)")
    compare.add_argument("--episodes", type=int, help="override the recorded episodes per level")
    compare.add_argument("--workers", type=int,
                         help="evaluate on N Ray simulator actors (default: in this process)")
    compare.add_argument("--html", metavar="FILE", action=LazyHelp, help_text=lambda: (
        f"HTML page to write (default DIR/compare-<A>-vs-<B>.html, each agent named as in audit's --out: "
        f"{default_compare_page('', cli_help.default_agent(), 'builtin:random')} for --agent "
        f"{cli_help.default_agent()} --agent builtin:random)"))
    compare.set_defaults(handler=run_compare_command)
    report = subparsers.add_parser(
        "report", help="write a collection's report.html again (with this version's report, or for a collection received)",
        description="Renders report.html from a collection's own files (collection.json, the level pictures, the "
                    "heatmap): reading them runs no code and evaluates nothing.")
    report.add_argument("collection", metavar="DIR", help="a collection folder, or the audit folder holding one")
    report.set_defaults(handler=run_report_command)
    add_series_subparser(subparsers)


def _slug(spec: str) -> str:
    """:func:`~dsage_ray.audit.collection.agent_slug`, imported only when the help that shows it is."""
    from dsage_ray.audit.collection import agent_slug

    return agent_slug(spec)


def flagged_domains() -> list:
    """The registrations of the domains whose audits take flags of their own (:class:`~dsage_ray.domains.AuditFlag`),
    in registry order; a plug-in that does not load has none."""
    from dsage_ray.domains import domain_names, get_domain
    from dsage_ray.errors import DsageError

    specs = []
    for name in domain_names():
        try:
            spec = get_domain(name)
        except DsageError:
            continue
        if spec.audit is not None and spec.audit.flags:
            specs.append(spec)
    return specs


def _dest(domain: str, key: str) -> str:
    # The section key, not the flag: two domains may name the same flag for different keys only if argparse
    # refuses it, and the value is read back by the key it sets.
    return f"{domain}.{key}"


def add_domain_arguments(parser) -> None:
    """Each domain's own audit flags (:attr:`~dsage_ray.domains.AuditSpec.flags`), one help group per domain."""
    for spec in flagged_domains():
        group = parser.add_argument_group(spec.audit.flags_title or f"--domain {spec.name}")
        for flag in spec.audit.flags:
            group.add_argument(flag.flag, dest=_dest(spec.name, flag.key), metavar=flag.metavar or flag.key.upper(),
                               action="append" if flag.repeat else None, help=flag.help)


def domain_flag_overrides(args: argparse.Namespace) -> dict:
    """The config keys the domains' own flags set; a flag of another domain than the audit's is refused."""
    given, misplaced = {}, []
    for spec in flagged_domains():
        flags = [flag for flag in spec.audit.flags if getattr(args, _dest(spec.name, flag.key), None) is not None]
        if spec.name != args.domain and flags:
            misplaced.append(f"{', '.join(flag.flag for flag in flags)}: only for --domain {spec.name}")
        for flag in flags:
            value = getattr(args, _dest(spec.name, flag.key))
            given[f"{spec.name}.{flag.key}"] = tuple(value) if isinstance(value, list) else value
    if misplaced:
        raise InputError(f"{'; '.join(misplaced)} (this audit's domain is {args.domain!r})")
    return given


def with_variant(variant: str | None, overrides: dict) -> dict:
    """``overrides`` with ``--variant``'s value as the ``variant`` key: ``--variant X`` is ``--set variant=X``,
    checked (and refused when unknown) in the same place, with the same message.

    Raises:
        InputError: ``--set variant=`` gives another value than ``--variant``.
    """
    if variant is None:
        return overrides
    given = overrides.get("variant", variant)
    if given != variant:
        raise InputError(f"--variant {variant} and --set variant={given} disagree: give one of them")
    return {**overrides, "variant": variant}


def run_audit_command(args: argparse.Namespace) -> int:
    """Handler of ``dsage-ray audit``: :func:`dsage_ray.run_audit`, then what it found.

    Errors end the command through :func:`dsage_ray.cli.main` (one line, the exit code of their kind).
    """
    from dsage_ray.audit.run import default_audit_folder, run_audit
    from dsage_ray.cli_args import config_overrides

    if args.agent is None:
        print(_demo_notice(args), flush=True)
    if args.out is None:  # named now: the first line says where it goes, and a Ctrl+C names it for --resume
        args.out = str(default_audit_folder(args.agent, domain=args.domain))
        print(f"audit folder: {args.out}", flush=True)
    measures = tuple(m.strip() for m in args.measures.split(",") if m.strip()) if args.measures else None
    overrides = with_variant(args.variant, {**domain_flag_overrides(args), **config_overrides(args)})
    collection = run_audit(
        agent=args.agent, domain=args.domain, reference=args.reference, preset=args.preset,
        objective=args.objective, measures=measures, budget=args.budget, seed=args.seed,
        overrides=overrides, out=args.out, local=args.local,
        workers=args.workers, address=args.address, resume=args.resume, episodes=args.episodes,
        max_levels=args.max_levels, collect_only=args.collect_only, expect_return=args.expect_return,
        allow_failing_nominal=args.allow_failing_nominal)
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


def run_report_command(args: argparse.Namespace) -> int:
    """Handler of ``dsage-ray report``: :func:`~dsage_ray.audit.report.write_report` of a collection folder."""
    from dsage_ray.audit.report import write_report

    folder = Path(args.collection)
    if (folder / "collection").is_dir() and not (folder / "collection.json").is_file():
        folder = folder / "collection"  # an audit folder
    print(f"report: {write_report(folder)}")
    return 0


def default_compare_page(collection: str | Path, a: str, b: str) -> Path:
    """``DIR/compare-<A>-vs-<B>.html``: where ``compare`` without ``--html`` writes its page."""
    from dsage_ray.audit.collection import agent_slug

    return Path(collection) / f"compare-{agent_slug(a)}-vs-{agent_slug(b)}.html"


def run_compare_command(args: argparse.Namespace) -> int:
    """Handler of ``dsage-ray compare``."""
    from dsage_ray.audit.compare import compare_agents, format_comparison

    if len(args.agent) != 2:
        raise InputError(f"give exactly two agents (--agent A --agent B), got {len(args.agent)}")
    for flag, value in (("--workers", args.workers), ("--episodes", args.episodes)):
        if value is not None and value < 1:
            raise InputError(f"{flag} must be positive, got {value}")
    a, b = args.agent
    html_path = Path(args.html) if args.html else default_compare_page(args.collection, a, b)
    comparison = compare_agents(a, b, collection_dir=args.collection, threshold=args.threshold,
                                episodes=args.episodes, html_path=html_path, workers=args.workers)
    print(format_comparison(comparison))
    print(f"\nHTML: {html_path}")
    return 0


SERIES_EXAMPLES = """\
examples:
  dsage-ray audit-series rllib:run/ckpt_1 rllib:run/ckpt_2 rllib:run/ckpt_3 --out tb_logs/series   # in this order
  dsage-ray audit-series builtin:random builtin:wall_follower --preset tiny --local --out /tmp/series  # a smoke test
  dsage-ray audit-series --watch tb_logs/ppo/checkpoints --pattern 'checkpoint_*' --out tb_logs/series_ppo
  dsage-ray audit-series dcd:a.tar dcd:b.tar --out tb_logs/series      # again: continues, skips what is recorded

Each checkpoint: its success on the regression suite (the failing levels earlier checkpoints' audits found,
with their recorded seeds), the suite levels fixed and regressed since the previous checkpoint, then a short
audit (default a quarter of the preset's budget) warm-started from the previous audit's surrogate, whose new
failing levels join the suite. A level fails when its failure rate is >= 0.5.
--watch DIR audits DIR's entries (files or folders matching --pattern) as KIND:PATH specs (--kind, default
rllib) in modification-time order, each once it has not changed for --poll seconds, and waits for new ones
until Ctrl+C (or --max-checkpoints). Python: dsage_ray.AuditSeries (docs/API.md).
"""


def add_series_subparser(subparsers) -> None:
    """Registers ``audit-series``."""
    from dsage_ray.audit import cli_help
    from dsage_ray.cli_args import LazyHelp, add_config_arguments, add_ray_arguments
    from dsage_ray.domains.agent_help import agent_kinds_help, checkpoint_kinds

    series = subparsers.add_parser(
        "audit-series", help="audit checkpoints in training order: a growing regression suite, a short search each",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Audits checkpoints of one agent in order (or as they appear with --watch) and writes "
                    "series.json,\nseries.html (timeline, table per checkpoint, level x checkpoint matrix), each "
                    "checkpoint's audit\nfolder and TensorBoard scalars audit/... into --out.",
        epilog=SERIES_EXAMPLES)
    series.add_argument("specs", nargs="*", metavar="SPEC", action=LazyHelp,
                        help_text=lambda: f"checkpoint agent specs, oldest first ({agent_kinds_help()})")
    series.add_argument("--out", required=True, metavar="DIR",
                        help="series folder (DIR/series.json, DIR/series.html, each checkpoint's audit in "
                             "DIR/checkpoints/<NNN>-<agent>, TensorBoard in DIR/tensorboard); one that holds "
                             "series.json is continued")
    series.add_argument("--domain", default=DEFAULT_DOMAIN, action=LazyHelp,
                        help_text=lambda: cli_help.domain_help(summaries=False))
    search = series.add_argument_group("each checkpoint's audit")
    add_config_arguments(search, preset_default="cpu")
    search.add_argument("--budget", type=int,
                        help="real evaluations per checkpoint (default: a quarter of the preset's, at least "
                             "n_rand + selection.count)")
    search.add_argument("--seed", type=int, default=0, help="run seed; checkpoint k's search uses SEED + k")
    search.add_argument("--episodes", type=int, action=LazyHelp,
                        help_text=lambda: cli_help.episodes_help("per level, in the suite and the collections"))
    search.add_argument("--no-warm-start", dest="warm_start", action="store_false",
                        help="start every search cold instead of from the previous audit's surrogate. "
                             "--surrogate-init FILE overrides both: every search then starts from FILE")
    watch = series.add_argument_group("watching a folder")
    watch.add_argument("--watch", metavar="DIR", help="audit new checkpoints of DIR as they appear (after the SPECs)")
    watch.add_argument("--kind", default="rllib", action=LazyHelp,
                       help_text=lambda: f"agent kind of the watched checkpoints, one of {', '.join(checkpoint_kinds())}"
                                         f": each entry is audited as KIND:PATH (default rllib)")
    watch.add_argument("--pattern", default="*",
                       help="glob of the entries of DIR that are checkpoints (default *, hidden entries never), "
                            "e.g. 'checkpoint_*' or '*.tar'")
    watch.add_argument("--poll", type=float, default=30.0,
                       help="seconds between looks at DIR; an entry is audited once it has not changed for this "
                            "long (default 30)")
    watch.add_argument("--max-checkpoints", type=int, metavar="N",
                       help="stop after auditing N checkpoints (recorded ones skipped do not count)")
    add_ray_arguments(series, resume=None)  # a series always continues what its --out holds
    series.set_defaults(handler=run_series_command)


def watched_checkpoints(folder, *, pattern: str = "*", settle: float = 0.0, now: float | None = None) -> list:
    """The checkpoints in ``folder`` to audit now, oldest first: its entries (files or folders) matching
    ``pattern``, hidden and ``*.tmp`` ones left out, whose newest file was modified at least ``settle``
    seconds before ``now`` (a checkpoint still being written waits); in order of that time, then name."""
    import os
    import time
    from pathlib import Path

    now = time.time() if now is None else now
    found = []
    for entry in Path(folder).glob(pattern):
        if entry.name.startswith(".") or entry.name.endswith(".tmp"):
            continue
        try:
            newest = entry.stat().st_mtime
            if entry.is_dir():
                for root, dirs, files in os.walk(entry):
                    dirs[:] = [d for d in dirs if not d.startswith(".")]
                    for name in files:
                        newest = max(newest, os.stat(os.path.join(root, name)).st_mtime)
        except OSError:  # removed while we looked: not a checkpoint to audit
            continue
        if now - newest >= settle:
            found.append((newest, entry.name, entry))
    return [entry for _, _, entry in sorted(found)]


def run_series_command(args: argparse.Namespace) -> int:
    """Handler of ``dsage-ray audit-series``: every SPEC, then (``--watch``) every new checkpoint, each through
    :meth:`dsage_ray.AuditSeries.audit`; bad input fails in one line before anything is written."""
    import sys
    import time
    from pathlib import Path

    from dsage_ray.audit.series import AuditSeries
    from dsage_ray.cli_args import config_overrides
    from dsage_ray.preflight import preflight

    if not args.specs and not args.watch:
        raise InputError("give checkpoint SPECs to audit in order, or --watch DIR (or both)")
    for flag, value in (("--poll", args.poll), ("--max-checkpoints", args.max_checkpoints)):
        if value is not None and value <= 0:
            raise InputError(f"{flag} must be positive, got {value}")
    watch = Path(args.watch) if args.watch else None
    if watch is not None and not watch.is_dir():
        raise InputError(f"--watch {watch}: no such folder")
    series = AuditSeries(out_dir=args.out, domain=args.domain, preset=args.preset, budget=args.budget, seed=args.seed,
                         overrides=config_overrides(args), local=args.local,
                         workers=args.workers, address=args.address, episodes=args.episodes,
                         warm_start=args.warm_start)
    # Every agent loads (and a watched kind is one the domain plays) before anything is written.
    for spec in args.specs:
        if series.recorded(spec) is None:
            preflight(series.config_for(spec))
    if watch is not None:
        series.config_for(f"{args.kind}:{watch}")

    audited: list = []
    busy = False

    def audit(spec: str, label: str | None = None) -> bool:
        """Audits one checkpoint (unless recorded) and prints its line; False once --max-checkpoints is reached."""
        nonlocal busy
        done = series.recorded(spec, label)
        if done is not None:
            print(f"#{done.index} {done.label}: already recorded, skipped", flush=True)
            return True
        print(f"#{len(series.records)} {label or spec}: auditing ...", flush=True)
        busy = True
        record = series.audit(spec, label=label)
        busy = False
        audited.append(record)
        print(_record_line(record), flush=True)
        return args.max_checkpoints is None or len(audited) < args.max_checkpoints

    interrupted = False
    try:
        going = all(audit(spec) for spec in args.specs)
        if watch is not None and going:
            print(f"watching {watch} for {args.pattern!r} every {args.poll:g} s (Ctrl+C stops)", flush=True)
            while going:
                # Absolute paths: a Tune trial runs in a folder of its own.
                new = [entry.resolve() for entry in watched_checkpoints(watch, pattern=args.pattern, settle=args.poll)]
                new = [entry for entry in new if series.recorded(f"{args.kind}:{entry}", entry.name) is None]
                for entry in new:
                    going = audit(f"{args.kind}:{entry}", label=entry.name)
                    if not going:
                        break
                else:
                    time.sleep(args.poll)
    except KeyboardInterrupt:
        interrupted = True
        print(f"\nstopped (Ctrl+C){' during an audit; it is not recorded' if busy else ''}", flush=True)
    _print_series_paths(series)
    failed = [r for r in audited if r.error]
    if failed:
        print(f"dsage-ray audit-series: {len(failed)} of {len(audited)} checkpoint audits failed (their error is in "
              f"series.json): " + "; ".join(f"#{r.index} {r.label}: {r.error}" for r in failed), file=sys.stderr)
    return 130 if interrupted and busy else 1 if failed else 0


def _record_line(record) -> str:
    """One line per audited checkpoint."""
    if record.error and not record.suite_size:
        return f"#{record.index} {record.label}: FAILED: {record.error}"
    success = "n/a" if record.suite_success_rate is None else f"{record.suite_success_rate:.3f}"
    line = (f"#{record.index} {record.label}: suite success {success} ({record.suite_size} levels), "
            f"{len(record.fixed)} fixed, {len(record.regressed)} regressed")
    if record.error:
        return f"{line}; audit FAILED: {record.error}"
    summary = record.summary
    return (f"{line}; {record.new_failures} new failures, {summary.get('never_solved', '?')} never solved, "
            f"{summary.get('failure_cells', '?')} failure cells ({record.wall_time / 60:.1f} min)")


def _print_series_paths(series) -> None:
    from dsage_ray.core.tensorboard_log import tensorboard_hint

    if not series.series_path.is_file():
        print("nothing recorded")
        return
    print(f"series: {series.series_path} ({len(series.records)} checkpoints, {len(series.suite)} suite levels)")
    print(f"report: {series.report_path}")
    print(f"TensorBoard: {tensorboard_hint(series.tensorboard_dir)}")
