"""``dsage-ray config`` and docs/CONFIG.md: one line per key, from the config's own fields."""

from pathlib import Path

from dsage_ray.cli import main
from dsage_ray.config_listing import key_lines, markdown

DOCS = Path(__file__).resolve().parents[1] / "docs" / "CONFIG.md"
STATUSES = {"paper", "tool", "default-on", "opt-in", "experimental"}


def test_the_docs_table_is_the_generated_one():
    assert DOCS.read_text() == markdown(), "regenerate it: python -m dsage_ray.config_listing > docs/CONFIG.md"


def test_the_default_listing_has_at_most_40_keys_each_with_a_status_and_experimental_ones_apart():
    run = key_lines()
    assert len(run) <= 40
    assert all(line.status in STATUSES - {"experimental"} for line in run)
    experimental = key_lines(experimental=True)[len(run):]
    assert experimental and all(line.key.startswith("experimental.") and line.status == "experimental" and line.note
                                for line in experimental)


def test_every_key_of_the_run_and_of_the_shipped_domains_has_a_note():
    # Plug-in domains installed beside the package are theirs to note, so only the shipped ones are checked.
    lines = key_lines(experimental=True) + [line for name in ("maze", "mario", "gym")
                                            for line in key_lines(domain=name)]
    assert {line.key for line in lines if line.status == "domain"} >= {"maze.agent", "mario.runs", "gym.space"}
    assert [line.key for line in lines if not line.note.strip()] == []


def test_the_command_prints_one_line_per_key_starting_with_its_full_name(capsys):
    assert main(["config"]) == 0
    printed = capsys.readouterr().out.splitlines()
    assert [line.split()[0] for line in printed] == [line.key for line in key_lines()]
    assert main(["config", "--domain", "gym", "--experimental"]) == 0
    keys = [line.split()[0] for line in capsys.readouterr().out.splitlines()]
    assert "gym.episodes" in keys and "experimental.screen_pool" in keys and "maze.episodes" not in keys


def test_an_unknown_domain_is_named(capsys):
    assert main(["config", "--domain", "mazee"]) == 2
    assert "--domain: unknown domain 'mazee'" in capsys.readouterr().err
