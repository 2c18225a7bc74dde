"""Each domain declares its own ``dsage-ray audit`` flags (``AuditSpec.flags``) and help (``AuditSpec.nominal``,
``.examples``...); the audit's CLI names no domain."""

from __future__ import annotations

import dataclasses
import re
from pathlib import Path

import pytest

from dsage_ray.audit import cli as audit_cli
from dsage_ray.audit import cli_help
from dsage_ray.audit.cli import domain_flag_overrides
from dsage_ray.cli import build_parser
from dsage_ray.domains import AuditFlag, AuditSpec, DomainSpec, register_domain, unregister_domain
from dsage_ray.errors import InputError


@dataclasses.dataclass
class TrackConfig:
    track: str = "oval"
    tyres: tuple[str, ...] = ()
    measures: tuple[str, ...] = ("a", "b")
    archive_dims: tuple[int, ...] = (4, 4)
    measure_ranges: tuple[tuple[float, float], ...] = ((0.0, 1.0), (0.0, 1.0))


FLAGS = (AuditFlag(flag="--track", key="track", metavar="NAME", help="the race track"),
         AuditFlag(flag="--tyre", key="tyres", metavar="KIND", repeat=True, help="a tyre set (repeat)"))


@pytest.fixture
def racing():
    spec = register_domain(DomainSpec(
        name="racing", config=TrackConfig, domain="tests.fakes:BitmapDomain", presets={"paper": {}},
        audit=AuditSpec(objectives=("failure_rate",), measures=("a", "b"), default_agent="random",
                        episodes_key="racing.episodes", flags=FLAGS, flags_title="a race track (--domain racing)",
                        summary="cars on a track", nominal="an empty oval", episodes_word="laps",
                        objective_notes={"failure_rate": "crashed laps"}, measures_note="the track's",
                        examples=("dsage-ray audit --domain racing --track monza --agent random   # a fast track",))))
    yield spec
    unregister_domain("racing")


def audit_help(capsys, command: str = "audit") -> str:
    with pytest.raises(SystemExit):
        build_parser().parse_args([command, "--help"])
    return capsys.readouterr().out


def one_line(text: str) -> str:
    """``text`` with argparse's wrapping undone."""
    return " ".join(text.split())


def test_a_plug_in_domain_brings_its_flags_in_a_group_of_its_own(racing, capsys):
    text = audit_help(capsys)
    group = text[text.index("a race track (--domain racing):"):]
    assert re.search(r"--track NAME +the race track", group) and re.search(r"--tyre KIND +a tyre set", group)
    # The shipped gym domain's flags are still there, in their group.
    assert "any Gymnasium environment (--domain gym):" in text and "--env-arg KEY=VALUE" in text


def test_a_domains_flags_set_its_keys_and_are_refused_for_another_domain(racing):
    parser = build_parser()
    args = parser.parse_args(["audit", "--domain", "racing", "--track", "monza", "--tyre", "soft", "--tyre", "wet"])
    assert domain_flag_overrides(args) == {"racing.track": "monza", "racing.tyres": ("soft", "wet")}
    args = parser.parse_args(["audit", "--track", "monza", "--env", "CartPole-v1"])
    with pytest.raises(InputError) as error:
        domain_flag_overrides(args)
    assert str(error.value) == ("--env: only for --domain gym; --track: only for --domain racing "
                                "(this audit's domain is 'maze')")


def test_the_audits_cli_names_no_domain():
    from dsage_ray.domains import domain_names

    for module in (audit_cli, cli_help):
        source = Path(module.__file__).read_text().lower()
        # Help texts and examples included: each domain says its own in its registration.
        named = sorted(name for name in {*domain_names(), "maze", "mario", "gym"} if name.lower() in source)
        assert not named, f"{module.__name__} names {named}"


def test_the_audit_help_says_what_each_shipped_domain_registers(capsys):
    from dsage_ray.domains import get_domain

    raw = audit_help(capsys)
    text = one_line(raw)
    epilog = raw[raw.index("examples:"):]
    for name in ("maze", "mario", "gym"):
        audit = get_domain(name).audit
        assert audit.examples and all(f"  {line}\n" in epilog for line in audit.examples), name
        assert f"{name}: {one_line(audit.nominal)}" in text, name
        assert f"{name}: {audit.default_agent}" in text, name
        if audit.measures_note:
            assert one_line(audit.measures_note) in text, name
    assert "episodes (mario: runs) per re-evaluation" in text
    assert "maze: failure_rate (default), regret, regression (the default with --reference)" in text
    assert "mario: incompletion (1 - completion)" in text
    assert "maze: search where --agent does worse than this agent" in text
    assert "one of maze (default), gym (any Gymnasium environment: --env, --space, --param), mario" in text
    # The demo paragraph reads the default domain's agent and cpu budget.
    assert "(maze: rllib:ppo_maze) with the domain's demo preset" in text and "(maze: 4,000 evaluations)" in text
    series = one_line(audit_help(capsys, "audit-series"))
    # The shipped domains, then any plug-in's.
    assert "one of maze (default), gym, mario" in series and "episodes (mario: runs) per level" in series


def test_a_plug_in_domain_says_its_own_help(racing, capsys):
    text = audit_help(capsys)
    assert "  dsage-ray audit --domain racing --track monza --agent random   # a fast track\n" in text
    text = one_line(text)
    for said in ("racing (cars on a track)", "racing: an empty oval", "racing: failure_rate (crashed laps)",
                 "racing: default a,b (the track's)", "racing: laps", "racing: random"):
        assert said in text, said
    assert "racing: laps" in one_line(audit_help(capsys, "audit-series"))


def test_building_the_parser_reads_no_domains_help(monkeypatch):
    # Listing the domains loads every registration: only --help needs it.
    monkeypatch.setattr(cli_help, "audited_domains", lambda: pytest.fail("read while building the parser"))
    build_parser()
