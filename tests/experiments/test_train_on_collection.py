"""``experiments/train_on_collection.py``: its test sets, training commands and table (the trainings themselves
are ``train_maze_agent.py``'s, tested in test_train_maze_agent.py)."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest

from dsage_ray.domains.maze.generator import random_valid_levels
from dsage_ray.domains.maze.layout import format_layout
from tests.integrations.conftest import write_collection
from tests.scripts import import_script

SCRIPT = Path(__file__).resolve().parents[2] / "experiments" / "train_on_collection.py"


@pytest.fixture
def script(monkeypatch):
    return import_script(SCRIPT, monkeypatch)


def test_the_unseen_set_is_the_fresh_audits_never_solved_levels_the_collection_lacks(tmp_path, script):
    levels = random_valid_levels(5, seed=3)
    write_collection(tmp_path / "train" / "collection", levels[:3])
    write_collection(tmp_path / "fresh_never", [levels[2], levels[3]])            # levels[2] was shown
    write_collection(tmp_path / "fresh_solved", [levels[4]], success=0.4)
    fresh = tmp_path / "fresh" / "collection"
    (fresh / "levels").mkdir(parents=True)
    never = json.loads((tmp_path / "fresh_never" / "collection.json").read_text())
    solved = json.loads((tmp_path / "fresh_solved" / "collection.json").read_text())["levels"][0]
    solved.update(id=2, level_file="levels/level_0002.txt", image_file="levels/level_0002.png")
    for i, level in enumerate([levels[2], levels[3], levels[4]]):
        (fresh / "levels" / f"level_{i:04d}.txt").write_text(format_layout(level))
    never["levels"].append(solved)
    (fresh / "collection.json").write_text(json.dumps(never))

    args = script.parse_args(["--collection", str(tmp_path / "train"), "--fresh", str(tmp_path / "fresh"),
                              "--mazes", "4", "--out", str(tmp_path / "out")])
    sets, shown_never = script.test_sets(args)
    assert shown_never == [0, 1, 2]                                # the shown levels were never solved
    assert [text for text, _ in sets["shown"]] == [format_layout(level) for level in levels[:3]]
    assert sets["unseen"] == [(format_layout(levels[3]), 101)]    # never solved, not shown, its recorded seed
    assert [seed for _, seed in sets["random"]] == [0, 1, 2, 3]


def test_only_the_mixed_arm_trains_on_the_collection_from_the_same_start(tmp_path, script):
    args = script.parse_args(["--collection", "c", "--fresh", "f", "--init-from", "ppo_maze", "--env-steps", "1000",
                              "--share", "0.5", "--out", str(tmp_path)])
    plain, mixed = script.train_command(args, "plain", 1), script.train_command(args, "mixed", 1)
    assert plain[plain.index("--init-from") + 1] == mixed[mixed.index("--init-from") + 1] == "ppo_maze"
    assert plain[plain.index("--seed") + 1] == mixed[mixed.index("--seed") + 1] == "1"
    assert "--train-on-collection" not in plain
    assert mixed[mixed.index("--train-on-collection") + 1] == str(Path("c").resolve())
    assert mixed[mixed.index("--collection-share") + 1] == "0.5"
    assert plain[:2] == [sys.executable, str(script.TRAIN_SCRIPT)]


def test_the_table_pairs_the_arms_by_seed(script, tmp_path):
    args = script.parse_args(["--collection", "c", "--fresh", "f", "--seeds", "0", "1", "--out", str(tmp_path)])
    sets = {"shown": [("", 0)] * 2, "unseen": [("", 0)], "random": [("", 0)] * 3}
    results = {"start": {"shown": [0.0, 1.0], "unseen": [0.0], "random": [1.0, 1.0, 1.0]},
               "plain_s0": {"shown": [0.0, 0.0], "unseen": [0.0], "random": [1.0, 1.0, 1.0]},
               "plain_s1": {"shown": [0.0, 1.0], "unseen": [0.2], "random": [1.0, 1.0, 1.0]},
               "mixed_s0": {"shown": [1.0, 1.0], "unseen": [0.4], "random": [1.0, 1.0, 0.4]},
               "mixed_s1": {"shown": [1.0, 0.0], "unseen": [0.4], "random": [1.0, 1.0, 1.0]}}
    table = script.summary_table(args, sets, results, shown_never=[0]).splitlines()
    assert table[0] == ("| agent | shown (2 levels) | shown, never solved (1) | unseen, never solved (1) | "
                        "random (3 mazes) |")
    assert table[2] == "| start (`ppo_maze`) | 0.500 | 0.000 | 0.000 | 1.000 |"
    assert table[3] == "| plain | 0.250 ± 0.250 | 0.000 ± 0.000 | 0.100 ± 0.100 | 1.000 ± 0.000 |"
    assert table[4] == "| mixed | 0.750 ± 0.250 | 1.000 ± 0.000 | 0.400 ± 0.000 | 0.900 ± 0.100 |"
    assert table[5] == ("| mixed - plain (paired by seed) | 0.500 ± 0.500 | 1.000 ± 0.000 | 0.300 ± 0.100 | "
                        "-0.100 ± 0.100 |")


def test_evaluations_are_reused_only_for_the_same_sets_and_settings(script, tmp_path):
    argv = ["--collection", "c", "--fresh", "f", "--out", str(tmp_path)]
    sets = {"shown": [("a", 1)], "unseen": [("b", 2)], "random": [("c", 0)]}
    key = script.evaluation_key(script.parse_args(argv), sets)
    assert key == script.evaluation_key(script.parse_args(argv + ["--jobs", "1"]), sets)
    assert key != script.evaluation_key(script.parse_args(argv + ["--episodes", "50"]), sets)
    assert key != script.evaluation_key(script.parse_args(argv), {**sets, "unseen": [("b", 3)]})


def test_a_folder_without_a_collection_stops_with_one_line_and_writes_nothing(script, tmp_path, capsys):
    (tmp_path / "empty").mkdir()
    out = tmp_path / "out"
    assert script.main(["--collection", str(tmp_path / "empty"), "--fresh", str(tmp_path / "empty"),
                        "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"error: --collection {tmp_path / 'empty'}: no collection.json (expected an audit's collection "
                   f"folder, or an audit folder holding collection/)"]
    assert not out.exists()
