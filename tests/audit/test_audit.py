"""Audit end to end on a tiny budget: a complete collection whose every number re-evaluates exactly."""

from __future__ import annotations

import dataclasses
import json
import re
import shlex
from pathlib import Path

import numpy as np
import pytest

from dsage_ray.audit.collection import audit_config, level_seed
from dsage_ray.audit.collection_file import load_collection
from dsage_ray.audit.compare import compare_agents, format_comparison
from dsage_ray.audit.report import region_statistics
from dsage_ray.cli import main

AUDITED = "builtin:random"


@pytest.fixture(scope="module")
def collection(tmp_path_factory) -> Path:
    """``dsage-ray audit --local`` on 24 random solutions (one outer iteration), 4 episodes per level."""
    out = tmp_path_factory.mktemp("audit")
    code = main(["audit", "--agent", AUDITED, "--preset", "tiny", "--budget", "24", "--set", "n_rand=24",
                 "--set", "maze.episodes=4", "--seed", "3", "--local", "--out", str(out)])
    assert code == 0
    return out / "collection"


def test_collection_is_complete(collection):
    c = load_collection(collection)
    assert c["format"] == "dsage_ray.collection.v2" and c["domain"] == "maze" and c["reference"] is None
    assert c["agent"] == AUDITED and c["objective"] == "failure_rate"
    assert c["measures"] == ["num_walls", "optimal_path_length"]
    assert c["config"]["preset"] == "tiny" and c["config"]["budget"] == 24 and c["run_seed"] == 3
    levels = c["levels"]
    assert 0 < len(levels) <= c["search_elites"]
    assert len(levels) == c["search_elites"] - c["search_invalid_elites"] - c["failed_reevaluations"]
    for key in ("id", "level_file", "image_file", "objective", "success_rate", "measures", "seed", "episodes",
                "reproduce", "search_objective", "search_measures", "layout_file", "layout", "start", "goal",
                "num_walls", "optimal_path_length", "mean_path_length", "episode_lengths", "explored_fraction",
                "repeated_visits"):
        assert all(key in lv for lv in levels), key
    assert not any("reference" in lv or "regression" in lv for lv in levels)
    for lv in levels:
        assert lv["layout_file"] == lv["level_file"]
        assert (collection / lv["layout_file"]).read_text() == lv["layout"]
        assert (collection / lv["image_file"]).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        assert len(lv["episode_lengths"]) == lv["episodes"] == 4
        assert lv["objective"] == pytest.approx(1 - lv["success_rate"])
    objectives = [lv["objective"] for lv in levels]
    assert objectives == sorted(objectives, reverse=True), "worst first"
    assert (collection / "heatmap.png").is_file()
    # Seeds follow the documented rule and are distinct.
    assert len({lv["seed"] for lv in levels}) == len(levels)
    assert {lv["seed"] for lv in levels} <= {level_seed(3, r) for r in range(c["search_elites"])}


def test_every_level_re_evaluates_to_its_recorded_numbers(collection, capsys):
    """Through the public CLI, with each level's own reproduce command."""
    c = load_collection(collection)
    for lv in c["levels"]:
        command = shlex.split(lv["reproduce"])
        assert command[:3] == ["dsage-ray", "maze", "eval"] and str(collection / lv["level_file"]) in command
        capsys.readouterr()
        assert main(command[1:] + ["--json"]) == 0
        again = json.loads(capsys.readouterr().out)
        assert again["success_rate"] == lv["success_rate"]
        assert again["mean_path_length"] == lv["mean_path_length"]
        assert again["episode_lengths"] == lv["episode_lengths"]
        assert [again["start"], again["goal"]] == [lv["start"], lv["goal"]]
        assert again["optimal_path_length"] == lv["optimal_path_length"] == lv["measures"]["optimal_path_length"]
        assert again["num_walls"] == lv["num_walls"] == lv["measures"]["num_walls"]


def test_report_is_self_contained(collection):
    page = (collection / "report.html").read_text()
    assert page.count("data:image/png;base64,") >= 2  # heatmap + at least one level
    for href in re.findall(r"href='([^']+)'", page):
        if href.startswith("#"):  # a level's row in the page
            assert f"id='{href[1:]}'" in page, f"broken link {href}"
        else:
            assert (collection / href).is_file(), f"broken link {href}"
    assert "Per-region statistics" in page


def test_region_statistics_partition_the_levels(collection):
    c = load_collection(collection)
    regions = region_statistics(c["levels"], c["measures"])
    assert sum(r["levels"] for r in regions) == len(c["levels"])
    ids = {lv["id"] for lv in c["levels"]}
    assert all(r["worst"] in ids and 0 <= r["min_success_rate"] <= r["success_rate"] <= 1 for r in regions)


def test_compare_uses_the_recorded_seeds(collection, tmp_path):
    """With A = the audited agent, A's column must equal the collection's numbers exactly."""
    html = tmp_path / "compare.html"
    comparison = compare_agents(AUDITED, "builtin:wall_follower", collection_dir=collection, html_path=html)
    recorded = {lv["id"]: lv for lv in load_collection(collection)["levels"]}
    assert len(comparison["levels"]) == len(recorded)
    for row in comparison["levels"]:
        assert row["success_a"] == recorded[row["id"]]["success_rate"]
        assert row["mean_path_length_a"] == recorded[row["id"]]["mean_path_length"]
        delta = row["success_b"] - row["success_a"]
        assert row["verdict"] == ("worse" if delta < -0.1 else "better" if delta > 0.1 else "same")
    deltas = [r["success_b"] - r["success_a"] for r in comparison["levels"]]
    assert deltas == sorted(deltas), "B's regressions first"
    s = comparison["summary"]
    assert s["b_worse"] + s["b_better"] <= s["levels"]
    assert s["success_a"] == pytest.approx(np.mean([lv["success_rate"] for lv in recorded.values()]))
    assert "B worse on" in format_comparison(comparison)
    assert html.read_text().startswith("<!DOCTYPE html>")


def test_compare_cli(collection, tmp_path, capsys):
    html = tmp_path / "c.html"
    assert main(["compare", "--agent", "builtin:wall_follower", "--agent", AUDITED, "--collection", str(collection),
                 "--html", str(html)]) == 0
    out = capsys.readouterr().out
    assert "A = builtin:wall_follower" in out and "B = builtin:random" in out and html.is_file()
    assert main(["compare", "--agent", AUDITED, "--collection", str(collection)]) == 2
    assert "dsage-ray compare: error: give exactly two agents" in capsys.readouterr().err


def test_audit_config_rejects_non_failure_objectives():
    with pytest.raises(ValueError, match="'failure_rate', 'regret', 'regression', got 'validity'"):
        audit_config(agent=AUDITED, objective="validity")
    config = audit_config(agent=AUDITED, objective="regret", measures=("num_walls", "mean_path_length"))
    assert config.maze.objective == "regret" and config.maze.archive_dims == (256, 648)


def test_search_auto_keeps_dsage_in_maze_audits_and_chooses_in_other_domains():
    """A Maze audit's picks cost past auto's break-even while DSAGE's audit finds the most failures at equal time."""
    maze = audit_config(agent=AUDITED, overrides={"search": "auto"})
    assert maze.search == "fixed" and maze.variant == "dsage" and maze.selection.elite_mutants == 150
    gym = audit_config(domain="gym", agent="random", preset="tiny", overrides={"search": "auto"})
    assert gym.search == "auto"
    assert audit_config(agent=AUDITED).search == "fixed"
    # An audit begun with auto before Maze audits kept DSAGE resumes as it began.
    begun = dataclasses.replace(maze, search="auto")
    assert audit_config(agent=AUDITED, overrides={"search": "auto"}, started=begun).search == "auto"


def test_a_cpu_audit_predicts_the_path_length_as_the_occupancy_sum_only_when_it_is_a_measure():
    # The Maze cpu preset turns the occupancy sum on; the default audit measures have no path length.
    default = audit_config(agent=AUDITED, preset="cpu").surrogate
    assert (default.occupancy_sum_measure, default.prior_measure) == ("", "")
    with_path = audit_config(agent=AUDITED, preset="cpu", measures=("num_walls", "mean_path_length"))
    assert with_path.surrogate.occupancy_sum_measure == "mean_path_length"
    assert with_path.surrogate.prior_measure == "mean_path_length"
    assert audit_config(agent=AUDITED, preset="cpu", variant="map_elites").surrogate.kind == "none"


def test_maze_audits_take_the_level_values_from_the_level_unless_told_otherwise():
    assert audit_config(agent=AUDITED, preset="cpu").surrogate.exact_level_values
    told = audit_config(agent=AUDITED, preset="cpu", overrides={"surrogate.exact_level_values": False})
    assert not told.surrogate.exact_level_values


def test_a_dsage_maze_audit_mutates_its_best_elites_and_other_searches_do_not():
    assert audit_config(agent=AUDITED, preset="cpu").selection.elite_mutants == 150
    assert audit_config(agent=AUDITED, preset="cpu", variant="dsage_only_down").selection.elite_mutants == 150
    told = audit_config(agent=AUDITED, preset="cpu", overrides={"selection.elite_mutants": 0})
    assert told.selection.elite_mutants == 0
    # A search without a surrogate would refuse the key; it is simply not added.
    for variant in ("map_elites", "dr"):
        assert audit_config(agent=AUDITED, preset="cpu", variant=variant).selection.elite_mutants == 0
    # Mario's registration declares no such key (not measured there).
    assert audit_config(domain="mario", agent="astar", preset="tiny").selection.elite_mutants == 0


def test_an_audit_resumes_with_the_defaults_it_began_with_and_names_a_changed_key(tmp_path, capsys):
    # An audit begun before the mutants became the default (as if) continues without them.
    # 8 random levels: the test reads the config the resume records, not the levels.
    args = ["audit", "--agent", AUDITED, "--preset", "tiny", "--budget", "8", "--set", "n_rand=8",
            "--set", "maze.episodes=4", "--local", "--out", str(tmp_path)]
    assert main([*args, "--set", "selection.elite_mutants=0"]) == 0
    (tmp_path / "search" / "config.json").unlink()  # as an interrupted search, which has written only its checkpoint
    assert main([*args, "--resume"]) == 0
    assert load_collection(tmp_path / "collection")["config"]["selection"]["elite_mutants"] == 0
    capsys.readouterr()
    assert main([*args, "--resume", "--seed", "5"]) == 2
    assert "different config: seed = 0, not 5" in capsys.readouterr().err


def test_a_gym_audit_resumes_with_the_preset_values_it_began_with(tmp_path):
    # Gym audits once took 15 elite mutants (an audit key) and another step size (a preset key, as if): an audit
    # begun then continues as it began, not with today's values, and not with an error.
    # A random agent never balances CartPole's 475 steps: its nominal check fails by rights, and this test is about
    # the resume, so it goes on.
    # One random iteration of 8 levels (no surrogate trained): the test reads the config the resume records.
    args = ["audit", "--domain", "gym", "--space", "cartpole", "--agent", "random", "--preset", "tiny", "--budget",
            "8", "--set", "n_rand=8", "--local", "--out", str(tmp_path), "--allow-failing-nominal"]
    assert main([*args, "--set", "qd.sigma0=0.3", "--set", "selection.elite_mutants=3"]) == 0
    (tmp_path / "search" / "config.json").unlink()  # as an interrupted search, which has written only its checkpoint
    assert main([*args, "--resume"]) == 0
    config = load_collection(tmp_path / "collection")["config"]
    assert (config["qd"]["sigma0"], config["selection"]["elite_mutants"]) == (0.3, 3)
    fresh = audit_config(domain="gym", agent="random", preset="tiny", overrides={"gym.space": "cartpole"})
    assert (fresh.qd.sigma0, fresh.selection.elite_mutants) == (0.2, 0)


def test_a_search_on_disk_reports_its_config_from_the_checkpoint_header(collection):
    from dsage_ray.audit.run import search_on_disk

    assert search_on_disk(collection.parent / "search").config.seed == 3


def test_audits_hold_no_levels_out_unless_asked():
    assert audit_config(agent=AUDITED, preset="cpu").experimental.holdout_levels == 0
    asked = audit_config(agent=AUDITED, preset="cpu", overrides={"experimental.holdout_levels": 30})
    assert asked.experimental.holdout_levels == 30


def test_an_audit_with_a_time_budget_searches_with_auto_unless_told_or_where_auto_cannot_run():
    timed = {"time_budget": 300.0}
    assert audit_config(domain="gym", agent="random", preset="tiny", overrides=timed).search == "auto"
    assert audit_config(domain="gym", agent="random", preset="tiny").search == "fixed"  # no time budget
    told = audit_config(domain="gym", agent="random", preset="tiny", overrides={**timed, "search": "fixed"})
    assert told.search == "fixed"
    assert audit_config(domain="gym", agent="random", preset="tiny", variant="cross_entropy",
                        overrides=timed).search == "fixed"  # no surrogate to pay for
    assert audit_config(domain="gym", agent="random", preset="tiny",
                        overrides={**timed, "pipeline": True}).search == "fixed"
    # Maze audits keep DSAGE; an audit continues with the search it began with.
    assert audit_config(agent=AUDITED, overrides=timed).search == "fixed"
    begun = audit_config(domain="gym", agent="random", preset="tiny")
    assert audit_config(domain="gym", agent="random", preset="tiny", overrides=timed, started=begun).search == "fixed"
