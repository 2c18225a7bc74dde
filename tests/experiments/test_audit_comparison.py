"""``experiments/audit_comparison.py``: audits per variant × seed, a table of their failure counts, resumable."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import pytest

REPO_ROOT = Path(__file__).resolve().parents[2]


def load_script():
    spec = importlib.util.spec_from_file_location("audit_comparison", REPO_ROOT / "experiments" / "audit_comparison.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


# Four audits in subprocesses; the audits themselves are covered by tests/audit, the arms by the tests below.
@pytest.mark.slow
def test_two_searches_two_seeds_one_table_and_a_rerun_runs_nothing(tmp_path, capsys):
    from dsage_ray.audit.collection_file import load_collection
    from dsage_ray.audit.summary import failure_summary

    script = load_script()
    out = tmp_path / "cmp"
    argv = ["--agent", "builtin:random", "--preset", "tiny", "--variants", "dsage,dr", "--seeds", "2",
            "--budget", "24", "--set", "n_rand=24", "--set", "maze.episodes=3", "--out", str(out)]
    assert script.main(argv) == 0
    printed = capsys.readouterr().out
    assert "4 audits to run" in printed and printed.count(": done in ") == 4, printed
    table = (out / "summary.md").read_text()
    means, per_audit = table.split("\n\nPer audit:\n\n")
    rows = {line.split("|")[1].strip(): line for line in means.splitlines()[2:]}
    assert sum(line.startswith("| ") for line in per_audit.splitlines()) == 1 + 4  # the heading, 2 arms × 2 seeds
    assert set(rows) == {"dsage", "dr"}
    runs = json.loads((out / "summary.json").read_text())
    for variant in ("dsage", "dr"):
        collections = [load_collection(out / f"{variant}_seed{seed}" / "collection") for seed in (0, 1)]
        assert {c["config"]["variant"] for c in collections} == {variant}
        assert [{k: run[k] for k in failure_summary(c)} for run, c in zip(runs[variant], collections)] == [
            failure_summary(c) for c in collections]
        assert [run["seed"] for run in runs[variant]] == [0, 1]
        assert all(0 < run["search_minutes"] < 30 for run in runs[variant])
        assert all(0 < run["search_cpu_s"] < 30 * 60 for run in runs[variant])
        never = [failure_summary(c)["never_solved"] for c in collections]
        assert rows[variant].split("|")[3].strip().startswith(f"{sum(never) / 2:,.1f} ± ")
    # Everything collected: a second call only rebuilds the table.
    assert script.main(argv) == 0
    assert "0 audits to run" in capsys.readouterr().out
    # More episodes per re-evaluation: every collection again, from the same searches.
    searched = [(out / f"dsage_seed{seed}" / "search" / "metrics.json").read_text() for seed in (0, 1)]
    assert script.main([*argv, "--episodes", "5"]) == 0
    assert "4 audits to run (2 variants × 2 seeds, 0 already collected, 4 to collect again with 5 episodes)" in (
        capsys.readouterr().out)
    assert {load_collection(out / f"{v}_seed{s}" / "collection")["episodes"] for v in ("dsage", "dr") for s in (0, 1)
            } == {5}
    assert [(out / f"dsage_seed{seed}" / "search" / "metrics.json").read_text() for seed in (0, 1)] == searched
    assert "re-evaluated with its recorded seed and 5 episodes." in (out / "summary.md").read_text()


def test_the_table_prints_every_audit_beside_the_means():
    script = load_script()
    run = {"never_solved": 12, "failure_cells": 340, "with_failures": 700, "levels": 1_500, "search_minutes": 7.04,
           "search_cpu_s": 417.9}
    table = script.per_seed_table({"elite": [run | {"seed": 22}, run | {"seed": 23, "never_solved": 9}],
                                   "map_elites": [run | {"seed": 22, "levels": 999}]})
    assert table.splitlines()[2:] == ["| elite | 22 | 12 | 340 | 700 | 1,500 | 7.0 | 418 |",
                                      "| elite | 23 | 9 | 340 | 700 | 1,500 | 7.0 | 418 |",
                                      "| map_elites | 22 | 12 | 340 | 700 | 999 | 7.0 | 418 |"]


def test_arms_are_labelled_variants_with_their_own_keys_on_the_seeds_asked_for(tmp_path):
    script = load_script()
    args = script.parse_args(["--variants", "cold=dsage,warm=dsage,dr", "--arm-set", "warm:surrogate.init=/x/y",
                              "--arm-set", "warm:experimental.init_prior=false", "--first-seed", "200", "--seeds", "2",
                              "--set", "maze.episodes=3", "--out", str(tmp_path)])
    assert script.parse_arms(args) == {"cold": "dsage", "warm": "dsage", "dr": "dr"}
    assert script.seeds(args) == [200, 201]
    warm = script.audit_command(args, "warm", 200, tmp_path / "warm_seed200")
    cold = script.audit_command(args, "cold", 200, tmp_path / "cold_seed200")
    assert warm[warm.index("--variant") + 1] == "dsage" and warm[warm.index("--seed") + 1] == "200"
    # Each arm is the search it names (an audit with a time budget would otherwise search with auto), unless its keys
    # name one.
    assert [warm[i + 1] for i, a in enumerate(warm) if a == "--set"] == [
        "search=fixed", "maze.episodes=3", "surrogate.init=/x/y", "experimental.init_prior=false"]
    assert [cold[i + 1] for i, a in enumerate(cold) if a == "--set"] == ["search=fixed", "maze.episodes=3"]
    auto = script.parse_args(["--variants", "dsage,auto=dsage", "--arm-set", "auto:search=auto"])
    assert [a for a in script.audit_command(auto, "auto", 0, tmp_path / "auto_seed0") if "search=" in a] == [
        "search=auto"]
    bad = script.parse_args(["--variants", "dsage", "--arm-set", "warm:surrogate.init=/x"])
    try:
        script.parse_arms(bad)
    except SystemExit as exc:
        assert "LABEL one of ['dsage']" in str(exc)
    else:
        raise AssertionError("an --arm-set of an unknown arm was accepted")


def test_match_time_gives_an_arm_the_time_its_seeds_reference_searched(tmp_path):
    script = load_script()
    args = script.parse_args(["--variants", "dsage,map_elites", "--match-time", "map_elites", "--budget", "100000",
                              "--first-seed", "10", "--out", str(tmp_path)])
    assert script.parse_arms(args) == {"dsage": "dsage", "map_elites": "map_elites"}
    search = tmp_path / "dsage_seed10" / "search"
    search.mkdir(parents=True)
    (search / "metrics.json").write_text(json.dumps([{"wall_time": 100.0, "cpu_time": 90.0},
                                                     {"wall_time": 361.25, "cpu_time": 350.0}]))
    matched = script.audit_command(args, "map_elites", 10, tmp_path / "map_elites_seed10")
    assert [matched[i + 1] for i, a in enumerate(matched) if a == "--set"] == ["search=fixed", "time_budget=361.2"]
    reference = script.audit_command(args, "dsage", 10, tmp_path / "dsage_seed10")
    assert not any(a.startswith("time_budget=") for a in reference)
    try:  # seed 11's reference has not run
        script.audit_command(args, "map_elites", 11, tmp_path / "map_elites_seed11")
    except SystemExit as exc:
        assert "the dsage audit of seed 11 has no search metrics" in str(exc)
    else:
        raise AssertionError("a matched arm ran without its reference's time")
    for argv, message in [(["--match-time", "dr"], "not an arm"), (["--match-time", "dsage", "--match-time",
                                                                      "map_elites"], "at least one arm")]:
        try:
            script.parse_arms(script.parse_args(["--variants", "dsage,map_elites", *argv]))
        except SystemExit as exc:
            assert message in str(exc)
        else:
            raise AssertionError(f"{argv} was accepted")


def test_episodes_recollects_an_audit_whose_collection_played_another_number(tmp_path):
    script = load_script()
    args = script.parse_args(["--variants", "dsage", "--episodes", "10", "--out", str(tmp_path)])
    folder = tmp_path / "dsage_seed0"
    assert script.to_run(args, "dsage", 0)  # nothing collected yet
    (folder / "search").mkdir(parents=True)
    command = script.audit_command(args, "dsage", 0, folder)
    assert command[command.index("--episodes") + 1] == "10" and "--resume" in command  # an interrupted search
    assert "--collect-only" not in command
    (folder / "collection").mkdir()
    (folder / "collection" / "collection.json").write_text(json.dumps({"episodes": 3, "levels": []}))
    assert script.to_run(args, "dsage", 0)  # re-evaluated with 3: collected again, from the finished search
    command = script.audit_command(args, "dsage", 0, folder)
    assert "--collect-only" in command and "--resume" not in command
    assert script.episodes_note(args, ["dsage"]) == " and 3 episodes"
    (folder / "collection" / "collection.json").write_text(json.dumps({"episodes": 10, "levels": []}))
    assert not script.to_run(args, "dsage", 0)
    assert not script.to_run(script.parse_args(["--variants", "dsage", "--out", str(tmp_path)]), "dsage", 0)
    assert script.episodes_note(args, ["dsage"]) == " and 10 episodes"
