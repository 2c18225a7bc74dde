"""What ``--help`` tells a newcomer, and what ``dsage-ray audit`` does without ``--agent``."""

from __future__ import annotations

import pytest

from dsage_ray.cli import main


def help_text(*command: str, capsys) -> str:
    with pytest.raises(SystemExit) as exit_:
        main([*command, "--help"])
    assert exit_.value.code == 0
    return capsys.readouterr().out


@pytest.mark.parametrize("command, groups", [
    (("run",), ("config:", "output:", "where it runs:")),
    (("ablate",), ("config:", "grid:", "output:", "where it runs:")),
    (("audit",), ("what to audit:", "the search:", "the collection:", "where it runs:")),
])
def test_run_ablate_and_audit_help_show_groups_and_examples(command, groups, capsys):
    text = help_text(*command, capsys=capsys)
    assert all(group in text for group in groups), text
    assert "examples:" in text and f"dsage-ray {command[0]} " in text.split("examples:")[1]


def test_the_preset_help_lists_every_preset_with_its_evaluations(capsys):
    text = " ".join(help_text("run", capsys=capsys).split())
    assert "maze: paper 100,000, cpu 4,000, demo 500, tiny 150" in text, text


def test_maze_eval_help_names_every_agent_kind(capsys):
    text = " ".join(help_text("maze", "eval", capsys=capsys).split())
    assert all(kind in text for kind in ("dcd:PATH", "rllib:PATH", "torchscript:PATH", "builtin:NAME")), text


def test_an_audit_without_agent_is_the_short_demo_and_says_so(monkeypatch, capsys):
    from dsage_ray.audit import run as audit_run

    seen = {}

    def fake_search(config, **kwargs):  # no search: what would have been searched
        seen["config"] = config
        raise SystemExit(0)

    monkeypatch.setattr(audit_run, "search_and_collect", fake_search)
    with pytest.raises(SystemExit):
        main(["audit", "--local"])
    out = capsys.readouterr().out
    assert out.startswith("no --agent: auditing the shipped demo agent rllib:ppo_maze with --preset demo "
                          "(500 evaluations)")
    assert seen["config"].preset == "demo" and seen["config"].budget == 500
    assert seen["config"].maze.agent == "rllib:ppo_maze"


def test_lazy_help_options_store_and_append_like_argparse_and_build_help_only_when_shown():
    import argparse

    from dsage_ray.cli_args import LazyHelp

    built = []

    def text() -> str:
        built.append(1)
        return "built on demand"

    parser = argparse.ArgumentParser(prog="x")
    parser.add_argument("--one", action=LazyHelp, help_text=text)
    parser.add_argument("--many", action=LazyHelp, append=True, help_text=text)
    parser.add_argument("rest", nargs="*", action=LazyHelp, help_text=text)
    args = parser.parse_args(["--one", "a", "--many", "b", "--many", "c", "d", "e"])
    assert (args.one, args.many, args.rest) == ("a", ["b", "c"], ["d", "e"])
    assert not built
    assert "built on demand" in parser.format_help() and built
