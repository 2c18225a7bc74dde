"""What the help says against what the commands do: where each writes by default (``--out`` and the like),
``audit --variant`` as ``--set variant=``, and the one list of agent kinds every ``--agent`` help shows."""

from __future__ import annotations

import argparse
import re
from pathlib import Path

import pytest

from dsage_ray.cli import build_parser, main

MAZE_CONFIG = str(Path(__file__).resolve().parents[1] / "experiments" / "configs" / "maze_dsage.toml")


class Stop(Exception):
    """Raised by a fake in place of the work, once it has seen where the work would go."""


def help_of(*command: str) -> str:
    """The help of ``dsage-ray COMMAND ...`` on one line (argparse's wrapping undone)."""
    parser = build_parser()
    for name in command:
        parser = _subcommands(parser)[name]
    return " ".join(parser.format_help().split())


def option_help(command: tuple[str, ...], option: str) -> str:
    """The help text of one option (or positional ``dest``) of a command, on one line."""
    parser = build_parser()
    for name in command:
        parser = _subcommands(parser)[name]
    for action in parser._actions:
        if option in action.option_strings or action.dest == option:
            return " ".join(str(action.help).split())
    raise AssertionError(f"{command} has no {option}")


def _subcommands(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    (sub,) = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    return dict(sub.choices)


def every_command(parser: argparse.ArgumentParser | None = None, prefix: tuple[str, ...] = ()):
    """``(command words, parser)`` of every leaf command."""
    parser = parser or build_parser()
    subs = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    if not subs:
        yield prefix, parser
        return
    for name, child in subs[0].choices.items():
        yield from every_command(child, prefix + (name,))


def template_regex(template: str, **parts: str) -> re.Pattern:
    """A help's ``<placeholder>`` path as a regex: named ``parts`` literally, ``<YYYYMMDD-HHMMSS>`` as a time."""
    pattern = re.escape(template).replace(re.escape("<YYYYMMDD-HHMMSS>"), r"\d{8}-\d{6}")
    for name, value in parts.items():
        pattern = pattern.replace(re.escape(f"<{name}>"), re.escape(value))
    return re.compile(pattern)


def without_time(path: str) -> str:
    """``path`` with its time stamp (or the ``...`` a help writes for one) as ``<time>``."""
    return re.sub(r"\d{8}-\d{6}|\.\.\.", "<time>", path)


# ------------------------------------------------------------------------------------------- --out

def test_audit_out_help_is_the_folder_default_audit_folder_names():
    from dsage_ray.audit.collection import agent_slug
    from dsage_ray.audit.run import default_audit_folder

    text = option_help(("audit",), "--out")
    template = re.search(r"default (tb_logs/audit-<agent>-<YYYYMMDD-HHMMSS>)", text)[1]
    for spec in ("rllib:ppo_maze", "dcd:runs/accel.tar", "builtin:random"):
        assert template_regex(template, agent=agent_slug(spec)).fullmatch(str(default_audit_folder(spec))), spec
    assert template_regex(template, agent=agent_slug("rllib:ppo_maze")).fullmatch(str(default_audit_folder(None)))
    # The help's own examples are what the function writes.
    examples = re.findall(r"(tb_logs/audit-\S+?) for (\S+?)[,)]", text)
    assert len(examples) == 2
    for example, spec in examples:
        assert without_time(example) == without_time(str(default_audit_folder(spec))), (example, spec)


def test_an_audit_prints_the_folder_its_help_describes_and_its_search_and_collection_go_inside(
        monkeypatch, tmp_path, capsys):
    from dsage_ray.audit import run as audit_run

    seen = {}

    def fake_search(config, *, out_dir, **kwargs):
        seen["out"] = Path(out_dir)
        raise Stop

    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(audit_run, "search_and_collect", fake_search)
    with pytest.raises(Stop):
        main(["audit", "--agent", "builtin:random", "--preset", "tiny", "--local"])
    printed = capsys.readouterr().out
    assert re.search(r"^audit folder: tb_logs/audit-builtin_random-\d{8}-\d{6}$", printed, re.M), printed
    assert printed.splitlines()[0] == f"audit folder: {seen['out']}"
    text = option_help(("audit",), "--out")
    assert f"DIR/{audit_run.SEARCH_DIR}" in text and f"DIR/{audit_run.COLLECTION_DIR}" in text


def test_run_out_help_is_where_a_local_run_and_a_tune_run_write(monkeypatch, tmp_path):
    from dsage_ray import runs
    from dsage_ray.config import RunConfig
    from dsage_ray.core import loop
    from dsage_ray.ray import launch

    text = option_help(("run",), "--out")
    local_default = re.search(r"--local: the run folder \(default (\S+),", text)[1]
    tune_default = re.search(r"through Tune: the storage folder or URI \(default (\w+);", text)[1]
    name = RunConfig.from_file(MAZE_CONFIG).name
    seen = {}

    def fake_local(config, *, out_dir, **kwargs):
        seen["local"] = Path(out_dir)
        raise Stop

    def fake_tune(config, *, out_dir, **kwargs):
        seen["tune"] = out_dir
        raise Stop

    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(runs, "preflight", lambda config: None)
    monkeypatch.setattr(loop, "run_locally", fake_local)
    monkeypatch.setattr(launch, "run_with_tune", fake_tune)
    for extra in (["--local"], []):
        with pytest.raises(Stop):
            main(["run", MAZE_CONFIG, "--preset", "tiny", *extra])
    assert seen["local"] == Path(local_default.replace("<name>", name))
    assert seen["tune"] == tune_default
    assert "<out>/<name>/<trial>" in text


def test_ablate_out_help_names_its_default():
    parser = _subcommands(build_parser())["ablate"]
    (out,) = [a for a in parser._actions if "--out" in a.option_strings]
    assert f"(default {out.default};" in help_of("ablate")


def test_pretrain_search_out_help_example_is_what_default_search_out_gives():
    from dsage_ray.surrogate_cli import default_search_out

    text = option_help(("surrogate", "pretrain"), "--search-out")
    search, out = re.search(r": (\S+) for --out (\S+?)\)", text).groups()
    assert default_search_out(Path(out)) == Path(search)


def test_compare_html_help_example_is_what_default_compare_page_gives():
    from dsage_ray.audit.cli import default_compare_page

    text = option_help(("compare",), "--html")
    assert "default DIR/compare-<A>-vs-<B>.html" in text
    page, a, b = re.search(r": (\S+\.html) for --agent (\S+) --agent (\S+?)\)", text).groups()
    assert default_compare_page("DIR", a, b) == Path("DIR") / page


def test_audit_series_out_help_names_its_files():
    from dsage_ray.audit import series

    text = option_help(("audit-series",), "--out")
    for name in (series.SERIES_FILE, series.SERIES_REPORT, series.CHECKPOINTS_DIR + "/<NNN>-<agent>",
                 series.TENSORBOARD_DIR):
        assert f"DIR/{name}" in text, name


# ---------------------------------------------------------------------------------------- --variant

def audit_args(tmp_path: Path, *extra: str) -> list[str]:
    return ["audit", "--agent", "builtin:random", "--preset", "tiny", "--local", "--out", str(tmp_path / "a"), *extra]


def searched_config(monkeypatch, argv: list[str]):
    """The config ``dsage-ray audit ARGV`` would search with (nothing is searched)."""
    from dsage_ray.audit import run as audit_run

    seen = {}

    def fake_search(config, **kwargs):
        seen["config"] = config
        raise Stop

    monkeypatch.setattr(audit_run, "search_and_collect", fake_search)
    with pytest.raises(Stop):
        main(argv)
    return seen["config"]


@pytest.mark.parametrize("flags", [["--variant", "map_elites"], ["--set", "variant=map_elites"],
                                   ["--variant", "map_elites", "--set", "variant=map_elites"]])
def test_audit_variant_is_set_variant(monkeypatch, tmp_path, flags):
    assert searched_config(monkeypatch, audit_args(tmp_path, *flags)).variant == "map_elites"


def test_audit_without_variant_searches_with_dsage(monkeypatch, tmp_path):
    assert searched_config(monkeypatch, audit_args(tmp_path)).variant == "dsage"


def test_an_unknown_variant_is_refused_alike_by_both_flags(tmp_path, capsys):
    errors = []
    for flags in (["--variant", "nope"], ["--set", "variant=nope"]):
        assert main(audit_args(tmp_path, *flags)) == 2
        errors.append(capsys.readouterr().err)
    assert errors[0] == errors[1] and "unknown variant 'nope'" in errors[0] and errors[0].count("\n") == 1


def test_variant_and_set_variant_that_disagree_are_refused_in_one_line(tmp_path, capsys):
    assert main(audit_args(tmp_path, "--variant", "map_elites", "--set", "variant=dr")) == 2
    err = capsys.readouterr().err
    assert err == "dsage-ray audit: error: --variant map_elites and --set variant=dr disagree: give one of them\n"
    assert "--set variant=" in option_help(("audit",), "--variant")


# ------------------------------------------------------------------------------------------- --agent

#: Every command with an agent spec argument, and the domain whose kinds it lists (None: every domain's).
AGENT_ARGUMENTS = {
    ("audit",): ("--agent", None),
    ("compare",): ("--agent", None),
    ("audit-series",): ("specs", None),
    ("surrogate", "pretrain"): ("--agent", None),
    ("maze", "eval"): ("--agent", "maze"),
    ("gym", "eval"): ("--agent", "gym"),
}


def plugin_commands() -> set[str]:
    """The commands installed plug-in domains add (``dsage-ray gridpath ...``): their help is the plug-in's own."""
    from dsage_ray.domains import domain_names, get_domain

    return {name for name in domain_names() if (get_domain(name).cli or "dsage_ray.").partition(".")[0] != "dsage_ray"}


def test_every_command_taking_an_agent_is_checked_here():
    taking = {words for words, parser in every_command()
              if any("--agent" in a.option_strings or a.dest == "specs" for a in parser._actions)}
    # dsage_ray's own commands, whatever plug-ins are installed beside it.
    assert {words for words in taking if words[0] not in plugin_commands()} == set(AGENT_ARGUMENTS)


@pytest.mark.parametrize("command", sorted(AGENT_ARGUMENTS))
def test_every_agent_help_lists_the_kinds_of_the_one_source(command):
    from dsage_ray.agents.loader import RUNS_CODE_NOTE
    from dsage_ray.domains import agent_forms

    option, domain = AGENT_ARGUMENTS[command]
    text = option_help(command, option)
    forms = agent_forms()
    if domain is None:
        listed = "; ".join(f"{name}: {', '.join(kinds)}" for name, kinds in forms.items())
    else:
        listed = ", ".join(forms[domain])
    assert f"({listed}. {RUNS_CODE_NOTE}" in text, text


def test_audit_series_kind_lists_the_kinds_that_name_a_checkpoint_file():
    from dsage_ray.domains.agent_help import checkpoint_kinds

    kinds = checkpoint_kinds()
    assert {"rllib", "dcd", "torchscript", "sb3"} <= set(kinds)
    assert not {"builtin", "astar[", "python", "random"} & set(kinds)  # named, generated or code, not a checkpoint
    assert f"one of {', '.join(kinds)}:" in " ".join(option_help(("audit-series",), "--kind").split())


def test_search_auto_is_the_same_as_set_search_and_both_must_agree(capsys):
    from dsage_ray.cli import main

    assert main(["run", "experiments/configs/maze_dsage.toml", "--search", "auto", "--set", "search=fixed",
                 "--local"]) == 2
    assert capsys.readouterr().err == "dsage-ray run: error: --search auto and --set search=fixed disagree: give one\n"
    assert "--set search=" in " ".join(option_help(("run",), "--search").split())
