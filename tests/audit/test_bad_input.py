"""Bad audit input: one clear error line before any search starts, and nothing written."""

from __future__ import annotations

import contextlib
import dataclasses
import io
import os

import pytest

from dsage_ray.audit.collection import audit_config
from dsage_ray.cli import main


def audit_error(argv: list[str]) -> str:
    """Runs ``dsage-ray audit ARGV``: exit code 2 and one error line on stderr, which it returns."""
    stderr = io.StringIO()
    with contextlib.redirect_stderr(stderr):
        assert main(["audit", *argv]) == 2
    message = stderr.getvalue()
    assert message.startswith("dsage-ray audit: error: ") and message.count("\n") == 1, message
    return message.rstrip("\n")


def test_unknown_domain(tmp_path):
    message = audit_error(["--domain", "zelda", "--out", str(tmp_path / "a")])
    assert "unknown domain 'zelda' (known: gym, mario, maze" in message
    assert audit_error(["--domain", "mazee", "--out", str(tmp_path / "a")]).endswith("; did you mean 'maze'?")
    assert not (tmp_path / "a").exists()


def test_a_domain_without_an_audit_declaration(tmp_path):
    from dsage_ray.domains import register_domain, unregister_domain
    from dsage_ray.domains.maze.plugin import DOMAIN

    register_domain(dataclasses.replace(DOMAIN, name="maze_no_audit", audit=None, cli=None))
    try:
        message = audit_error(["--domain", "maze_no_audit", "--out", str(tmp_path / "a")])
    finally:
        unregister_domain("maze_no_audit")
    assert "domain 'maze_no_audit' declares no audit (auditable: gym, mario, maze" in message


def test_reference_that_fails_to_load(tmp_path):
    message = audit_error(["--agent", "builtin:random", "--reference", "builtin:nope", "--local",
                           "--out", str(tmp_path / "a")])
    assert "reference agent" in message and "builtin:nope" in message
    assert not (tmp_path / "a").exists()


def test_agent_that_fails_to_load(tmp_path):
    message = audit_error(["--agent", f"dcd:{tmp_path / 'missing.tar'}", "--local", "--out", str(tmp_path / "a")])
    assert message.startswith("dsage-ray audit: error: agent 'dcd:") and "missing.tar" in message
    assert not (tmp_path / "a").exists()


def test_mario_agent_that_does_not_exist(tmp_path):
    message = audit_error(["--domain", "mario", "--agent", "dijkstra", "--out", str(tmp_path / "a")])
    assert message.endswith("domain 'mario' does not play 'dijkstra' agents (agent spec 'dijkstra'); its agents: "
                            "astar[:ITERATIONS]")
    assert "unknown Mario agent 'astar:fast' (known: astar, astar:ITERATIONS" in audit_error(
        ["--domain", "mario", "--agent", "astar:fast", "--out", str(tmp_path / "a")])
    assert not (tmp_path / "a").exists()


def test_an_agent_kind_of_another_domain_names_the_kinds_the_domain_plays(tmp_path):
    """Agent kinds are registered per domain: the error says which kinds the domain plays, and who plays this one."""
    message = audit_error(["--domain", "mario", "--agent", "dcd:accel", "--out", str(tmp_path / "a")])
    assert message.endswith("domain 'mario' does not play 'dcd' agents (agent spec 'dcd:accel'); its agents: "
                            "astar[:ITERATIONS]; 'dcd' agents are played by: maze")
    message = audit_error(["--agent", "astar:200", "--out", str(tmp_path / "a")])
    assert "domain 'maze' does not play 'astar' agents" in message and "dcd:PATH, rllib:PATH" in message
    assert message.endswith("'astar' agents are played by: mario")
    assert "does not play 'astar' agents" in audit_error(["--agent", "builtin:random", "--reference", "astar",
                                                          "--out", str(tmp_path / "a")])
    assert not (tmp_path / "a").exists()


def test_help_lists_the_agent_kinds_of_each_domain(capsys):
    with pytest.raises(SystemExit):
        main(["audit", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert "maze: builtin:NAME," in text and "rllib:PATH" in text and "mario: astar[:ITERATIONS]" in text


def test_objectives_and_references_that_do_not_fit(tmp_path):
    assert "needs a reference agent" in audit_error(["--objective", "regression", "--out", str(tmp_path / "a")])
    assert "Maze-only" in audit_error(["--domain", "mario", "--reference", "astar", "--out", str(tmp_path / "a")])
    assert "'incompletion', got 'failure_rate'" in audit_error(
        ["--domain", "mario", "--objective", "failure_rate", "--out", str(tmp_path / "a")])
    assert "unknown maze measure 'walls'" in audit_error(["--measures", "walls", "--out", str(tmp_path / "a")])
    assert not (tmp_path / "a").exists()


def test_out_folder_rules(tmp_path):
    existing = tmp_path / "old"
    (existing / "collection").mkdir(parents=True)
    message = audit_error(["--agent", "builtin:random", "--local", "--out", str(existing)])
    assert "already holds an audit: pass --resume" in message
    assert "nothing to resume" in audit_error(["--agent", "builtin:random", "--local", "--resume",
                                               "--out", str(tmp_path / "empty")])
    assert "nothing to collect from" in audit_error(["--agent", "builtin:random", "--local", "--collect-only",
                                                     "--out", str(tmp_path / "empty")])
    assert sorted(p.name for p in tmp_path.iterdir()) == ["old"]


def test_an_out_folder_another_audit_writes_or_that_cannot_be_written_stops_before_the_search(tmp_path):
    from dsage_ray.io import folder_lock

    with folder_lock(tmp_path / "busy", what="audit"):  # as a running audit holds it (flock: per open file)
        message = audit_error(["--agent", "builtin:random", "--preset", "tiny", "--local", "--out",
                               str(tmp_path / "busy")])
        assert sorted(p.name for p in (tmp_path / "busy").iterdir()) == [".dsage_ray.lock"]  # nothing more
    assert f"another audit is writing this folder (process {os.getpid()})" in message
    assert not (tmp_path / "busy").exists()  # its holder wrote nothing: it leaves no folder
    (tmp_path / "a_file").write_text("")
    message = audit_error(["--agent", "builtin:random", "--preset", "tiny", "--local", "--out",
                           str(tmp_path / "a_file" / "audit")])
    assert "a_file/audit: cannot write the audit's output there (Not a directory)" in message


def test_mario_audit_config_uses_the_paper_measures_and_the_agent_spec():
    config = audit_config(domain="mario", agent="astar:250", preset="tiny")
    assert config.mario.objective == "incompletion" and config.mario.astar_iterations == 250
    assert config.mario.measures == ("sky_tiles", "mean_jumps")
    assert config.mario.archive_dims == (150, 100) and config.mario.measure_ranges == ((0.0, 150.0), (0.0, 100.0))
    assert audit_config(domain="mario").mario.astar_iterations == 1000  # plain "astar": the config's default


def test_unknown_variant(tmp_path):
    message = audit_error(["--agent", "builtin:random", "--variant", "map_elite", "--local", "--out", str(tmp_path / "a")])
    assert "unknown variant 'map_elite'" in message and message.endswith("did you mean 'map_elites'?")
    assert not (tmp_path / "a").exists()


def test_ctrl_c_names_the_command_that_continues_the_audit_with_its_folder(monkeypatch, capsys):
    import dsage_ray.audit.run

    def interrupted(**kwargs):
        assert kwargs["out"].startswith("tb_logs/audit-builtin_random-")  # named before the search starts
        raise KeyboardInterrupt

    monkeypatch.setattr(dsage_ray.audit.run, "run_audit", interrupted)
    assert main(["audit", "--agent", "builtin:random", "--preset", "tiny"]) == 130
    out, err = capsys.readouterr()
    folder = out.split("audit folder: ", 1)[1].split()[0]
    assert err == (f"dsage-ray audit: error: interrupted; continue with: dsage-ray audit --agent builtin:random "
                   f"--preset tiny --out {folder} --resume\n")
