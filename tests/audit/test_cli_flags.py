"""Each domain declares its own ``dsage-ray audit`` flags (``AuditSpec.flags``); the audit's CLI names no domain."""

from __future__ import annotations

import dataclasses
import re
from pathlib import Path

import pytest

from dsage_ray.audit import cli as audit_cli
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
                        episodes_key="racing.episodes", flags=FLAGS, flags_title="a race track (--domain racing)")))
    yield spec
    unregister_domain("racing")


def audit_help(capsys) -> str:
    with pytest.raises(SystemExit):
        build_parser().parse_args(["audit", "--help"])
    return capsys.readouterr().out


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
    source = Path(audit_cli.__file__).read_text()
    code = "\n".join(line for line in source.splitlines() if not line.lstrip().startswith(("#", "dsage-ray ")))
    # Help texts may give examples; the code itself tests no domain's name.
    assert not re.search(r"""(==|!=|\bin)\s*\(?["'](gym|maze|mario)["']""", code)
    assert "GYM" not in source and "add_gym_arguments" not in source and "default=\"maze\"" not in source
