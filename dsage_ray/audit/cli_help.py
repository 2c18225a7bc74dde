"""The per-domain parts of the help of ``dsage-ray audit``, ``compare`` and ``audit-series``, read from each
domain's registration (:class:`~dsage_ray.domains.AuditSpec`) when help is shown.

The audits' CLI names no domain: each domain says its own help, so a plug-in domain's appears beside the
shipped ones' and a shipped one's wording lives with the rest of its registration. Every function here is
called from a :class:`~dsage_ray.cli_args.LazyHelp` or a lazy epilog, never while the parser is built, because
listing the domains loads every registration.
"""

from __future__ import annotations

import textwrap

from dsage_ray.domains.registry import DEFAULT_DOMAIN, DomainSpec

#: Width of the paragraphs wrapped here: the audit's help keeps its description and epilog as written
#: (RawDescriptionHelpFormatter), and its hand-written paragraphs are this wide.
WIDTH = 105


def audited_domains() -> list[DomainSpec]:
    """The registrations of the domains that declare audits: the default domain first, then in registry order.

    A plug-in that does not load is left out: help still shows, and using that domain reports why.
    """
    from dsage_ray.domains import domain_names, get_domain
    from dsage_ray.errors import DsageError

    specs = []
    for name in sorted(domain_names(), key=lambda name: name != DEFAULT_DOMAIN):  # stable: registry order after
        try:
            spec = get_domain(name)
        except DsageError:
            continue
        if spec.audit is not None:
            specs.append(spec)
    return specs


def per_domain(texts: dict[str, str]) -> str:
    """``NAME: A; OTHER: B``: each domain's non-empty text after its name."""
    return "; ".join(f"{name}: {text}" for name, text in texts.items() if text)


def default_agent() -> str:
    """The agent an audit of the default domain plays without ``--agent`` (the help's example of a spec)."""
    from dsage_ray.domains import get_domain

    audit = get_domain(DEFAULT_DOMAIN).audit
    return audit.default_agent if audit is not None else "builtin:random"


def domain_help(*, summaries: bool = True) -> str:
    """``--domain``'s help: every domain with audits, the default marked, each with its summary."""
    listed = []
    for spec in audited_domains():
        words = [*(["default"] if spec.name == DEFAULT_DOMAIN else []),
                 *([spec.audit.summary] if summaries and spec.audit.summary else [])]
        listed.append(spec.name + (f" ({'; '.join(words)})" if words else ""))
    return f"one of {', '.join(listed)}: every installed domain that declares audits, a plug-in's included"


def demo_agents() -> str:
    """``NAME: SPEC; ...``: the agent each domain audits without ``--agent``."""
    return per_domain({spec.name: spec.audit.default_agent for spec in audited_domains()})


def reference_help() -> str:
    """``--reference``'s help, naming the domains whose audits have the ``regression`` objective."""
    players = [spec.name for spec in audited_domains() if "regression" in spec.audit.objectives]
    where = f"{', '.join(players)}: " if players else "a domain with the regression objective: "
    return f"{where}search where --agent does worse than this agent, on the same seeds (objective regression)"


def nominal_help() -> str:
    """The description of the nominal check's help group: what each domain's nominal level is."""
    levels = per_domain({spec.name: spec.audit.nominal for spec in audited_domains()})
    return textwrap.fill(
        f"Before the search the agent plays the domain's nominal level{f' ({levels})' if levels else ''}. The audit "
        "stops where it does far worse there than expected (below E - max(0.25*|E|, 3 standard errors)), or never "
        "succeeds there when no return is expected (docs/GUIDE.md)", WIDTH)


def objective_help() -> str:
    """``--objective``'s help: each domain's objectives, its default and their notes."""
    texts = {}
    for spec in audited_domains():
        audit = spec.audit
        listed = []
        for objective in audit.objectives:
            # The first is the default; a sole objective needs no saying so.
            notes = [*(["default"] if objective == audit.objectives[0] and len(audit.objectives) > 1 else []),
                     *(["the default with --reference"] if objective == "regression" else []),
                     *([audit.objective_notes[objective]] if objective in audit.objective_notes else [])]
            listed.append(objective + (f" ({', '.join(notes)})" if notes else ""))
        texts[spec.name] = ", ".join(listed)
    return f"what the search maximises on valid levels. {per_domain(texts)}"


def measures_help() -> str:
    """``--measures``' help: each domain's default measures and what it says of them."""
    texts = {}
    for spec in audited_domains():
        default, note = ",".join(spec.audit.measures), spec.audit.measures_note
        if default or note:
            texts[spec.name] = "default " + (f"{default} ({note})" if default and note else default or note)
    return f"comma-separated measures. {per_domain(texts)}"


def episodes_help(what: str) -> str:
    """``episodes (NAME: runs) WHAT``: the help of an ``--episodes``, naming the domains that call them otherwise."""
    words = per_domain({spec.name: spec.audit.episodes_word for spec in audited_domains()
                        if spec.audit.episodes_word != "episodes"})
    return f"episodes{f' ({words})' if words else ''} {what}"


def audit_epilog() -> str:
    """``dsage-ray audit --help``'s epilog: every domain's examples, then what an audit without ``--agent`` is."""
    from dsage_ray.audit.run import AGENT_PRESET, DEMO_PRESET
    from dsage_ray.cli_args import preset_budgets

    specs = audited_domains()
    lines = [line for spec in specs for line in spec.audit.examples]
    demo = (f"Without --agent the audit is a short demo on the domain's shipped agent ({DEFAULT_DOMAIN}: "
            f"{default_agent()}) with the domain's {DEMO_PRESET} preset, and says so; a named agent gets the "
            f"{AGENT_PRESET} preset")
    budget = preset_budgets(DEFAULT_DOMAIN).get(AGENT_PRESET) if any(s.name == DEFAULT_DOMAIN for s in specs) else None
    demo += f" ({DEFAULT_DOMAIN}: {budget:,} evaluations)." if budget else "."
    head = "examples:\n" + "".join(f"  {line}\n" for line in lines) + "\n" if lines else ""
    return (f"{head}{textwrap.fill(demo, WIDTH)}\n"
            "Python: dsage_ray.run_audit() takes the same arguments and returns the collection (docs/API.md).\n")
