"""The ``--audit-*`` flags that the RLlib training scripts share (``experiments/train_maze_agent.py``,
``experiments/train_gym_agent.py``): their checks, the callback they configure and the lines they print.

A script's ``Args`` declares ``audit_every``, ``audit_budget``, ``audit_preset``, ``audit_episodes``,
``audit_background``, ``seed`` and ``num_cpus``; the script calls :func:`check_audit_flags` before anything
runs, ``config.callbacks(audit_callback(args, run_dir, writer, domain=..., overrides=...))`` when
``--audit-every`` is set, :func:`print_audit` on ``result["audit"]`` after each iteration, and
:func:`finish_audits_and_report` after the last one (before ``algo.stop()``). Importing this module imports
neither Ray nor torch.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Mapping

from dsage_ray.integrations import DEFAULT_EPISODES, DEFAULT_OVERRIDES


def check_audit_flags(args: Any, *, domain: str = "maze", overrides: Mapping[str, Any] | None = None) -> None:
    """Raises InputError, naming the flags, when the ``--audit-*`` flags cannot work together.

    With ``--audit-every`` set, the audits' config (``domain``, the preset, the budget, ``overrides`` over
    :data:`~dsage_ray.integrations.DEFAULT_OVERRIDES`) is checked too, so that a budget below the search's
    ``n_rand`` or an unknown preset stops the script before training rather than skipping every audit.
    """
    from dsage_ray.errors import InputError

    if args.audit_every < 0 or args.audit_budget < 1 or args.audit_episodes < 0:
        raise InputError("--audit-every and --audit-episodes must be >= 0, --audit-budget >= 1")
    if args.audit_every and args.audit_background and args.num_cpus < 2:
        raise InputError(f"background audits need a CPU of their own: --num-cpus {args.num_cpus} leaves none "
                         f"(raise it, or audit between iterations with --no-audit-background)")
    if args.audit_every:
        from dsage_ray.audit.collection import audit_config

        try:
            audit_config(domain=domain, agent=None, preset=args.audit_preset, budget=args.audit_budget,
                         seed=args.seed, overrides={**DEFAULT_OVERRIDES, **dict(overrides or {})})
        except ValueError as exc:  # InputError, ConfigError
            raise InputError(f"the audits' settings (--audit-preset {args.audit_preset}, --audit-budget "
                             f"{args.audit_budget}): {exc}") from None


def audit_callback(args: Any, run_dir: Path, writer: Any, *, domain: str = "maze",
                   overrides: Mapping[str, Any] | None = None):
    """``--audit-every``: the RLlib callback factory (modules in ``run_dir/checkpoints``, series in
    ``run_dir/audit_series``, scalars to ``writer``), auditing in ``domain`` with the config ``overrides``."""
    from dsage_ray.integrations.rllib import AuditCallback

    return AuditCallback.configured(audit_every=args.audit_every, audit_budget=args.audit_budget, out_dir=run_dir,
                                    writer=writer, preset=args.audit_preset, seed=args.seed,
                                    background=args.audit_background, domain=domain,
                                    overrides=dict(overrides or {}),
                                    episodes=args.audit_episodes or DEFAULT_EPISODES)


def print_audit(audit: Mapping[str, Any]) -> None:
    """One line per audit that ended (``result["audit"]``)."""
    success = audit.get("suite_success_rate")
    print(f"  audit of iteration {audit.get('checkpoint_iteration', '?')}: suite success "
          f"{'-' if success is None else f'{success:.3f}'}  fixed {audit.get('fixed', 0):.0f}  "
          f"regressed {audit.get('regressed', 0):.0f}  new failures {audit.get('new_failures', 0):.0f}  "
          f"never solved {audit.get('never_solved', 0):.0f}  {audit.get('wall_time', 0):.0f} s", flush=True)


def finish_audits_and_report(algo: Any, run_dir: Path) -> None:
    """After the last iteration: waits for a background audit still running, prints the audits that ended here
    and where the series is."""
    from dsage_ray.integrations.rllib import finish_audits

    print("waiting for the last audit ...", flush=True)
    for iteration, record, _ in finish_audits(algo):
        if record is not None:
            print_audit({k.removeprefix("audit/"): v for k, v in record.scalars().items()}
                        | {"checkpoint_iteration": iteration})
    print(f"audit series: {run_dir / 'audit_series'}", flush=True)
