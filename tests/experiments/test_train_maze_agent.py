"""``experiments/train_maze_agent.py``: ``--train-on-collection DIR`` makes a share of the training episodes replay
the collection's levels, from the env's seeded rng; a folder that is not a Maze collection, or background audits
without a CPU for them, stop the script with one clear line."""

from __future__ import annotations

import json
import sys

import numpy as np
import pytest

from dsage_ray.domains.maze.generator import random_valid_levels
from dsage_ray.domains.maze.layout import format_layout
from dsage_ray.errors import InputError
from tests.integrations.conftest import SCRIPT, write_collection
from tests.scripts import import_script

sys.path.insert(0, str(SCRIPT.parent))  # the training env lives beside the training script

from maze_training_env import RandomMazeEnv, make_random_maze_env  # noqa: E402


@pytest.fixture
def script(monkeypatch):
    """``experiments/train_maze_agent.py`` imported as a module (kept in ``sys.modules`` for tyro)."""
    return import_script(SCRIPT, monkeypatch)


@pytest.fixture
def collection(tmp_path):
    levels = random_valid_levels(3, seed=7)
    return write_collection(tmp_path / "audit" / "collection", levels), levels


def sources(env, episodes: int, seed: int) -> list[int]:
    out = []
    for i in range(episodes):
        _, info = env.reset(seed=seed if i == 0 else None)
        out.append(info["source_level"])
    return out


def test_a_share_of_the_episodes_replays_the_collection_levels(collection, script):
    folder, levels = collection
    args = script.parse_args(["--train-on-collection", str(folder), "--collection-share", "0.5"])
    texts = script.collection_levels(args.train_on_collection)
    assert texts == [format_layout(level) for level in levels]
    env_config = script.build_config(args, texts).env_config
    assert env_config["level_share"] == 0.5 and len(env_config["levels"]) == 3
    env = make_random_maze_env({**env_config, "difficulty": 1.0})
    played = []
    for i in range(60):
        _, info = env.reset(seed=11 if i == 0 else None)
        if info["source_level"] >= 0:
            level = env.unwrapped._maze.level
            expected = levels[info["source_level"]]
            assert np.array_equal(level.walls, expected.walls) and (level.start, level.goal) == (expected.start, expected.goal)
        played.append(info["source_level"])
    share = np.mean([s >= 0 for s in played])
    assert 0.3 < share < 0.7 and set(played) == {-1, 0, 1, 2}
    # Seeded: the same sequence again; and an audit folder (holding collection/) names the same levels.
    assert sources(make_random_maze_env({**env_config, "difficulty": 1.0}), 60, seed=11) == played
    assert script.collection_levels(folder.parent) == texts


def test_without_levels_the_random_mazes_are_unchanged():
    plain, mixed = RandomMazeEnv(), RandomMazeEnv(levels=[], level_share=0.5)
    for i in range(5):
        a, _ = plain.reset(seed=3 if i == 0 else None)
        b, _ = mixed.reset(seed=3 if i == 0 else None)
        assert np.array_equal(a["image"], b["image"])
        assert np.array_equal(plain._maze.level.walls, mixed._maze.level.walls)


def test_bad_levels_and_shares_are_refused():
    with pytest.raises(InputError, match="level 0 is 4x5; the training mazes are 16x16"):
        RandomMazeEnv(levels=["S....\n.....\n.....\n....G\n"])
    with pytest.raises(InputError, match="not a probability"):
        RandomMazeEnv(levels=[format_layout(random_valid_levels(1, seed=0)[0])], level_share=1.5)


@pytest.mark.parametrize("case, message", [
    ("missing", "no such folder"),
    ("empty", "no collection.json"),
    ("garbage", "not a readable collection"),
    ("mario", "a mario collection; the maze agent trains on maze levels"),
    ("no_levels", "the collection holds no levels"),
    ("bad_level", "level_0000.txt:2: ragged rows"),
    ("small", "is 4x4; the training mazes are 16x16"),
])
def test_a_bad_folder_stops_the_script_with_one_line(tmp_path, script, capsys, case, message):
    folder = tmp_path / "c"
    if case != "missing":
        folder.mkdir()
    if case == "garbage":
        (folder / "collection.json").write_text("{not json")
    elif case == "mario":
        write_collection(tmp_path / "m", random_valid_levels(1, seed=0), domain="mario")
        folder = tmp_path / "m"
    elif case == "no_levels":
        write_collection(tmp_path / "n", [])
        folder = tmp_path / "n"
    elif case in ("bad_level", "small"):
        write_collection(tmp_path / "b", random_valid_levels(1, seed=0))
        folder = tmp_path / "b"
        text = "S...\n....\n....\n...G\n" if case == "small" else "S..\n....\n"
        (folder / "levels" / "level_0000.txt").write_text(text)
    assert script.main(["--train-on-collection", str(folder), "--run-name", str(tmp_path / "run")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"error: --train-on-collection {folder}: ")
    assert message in err[0]
    assert not (tmp_path / "run").exists()


def test_background_audits_without_a_cpu_for_them_are_refused(tmp_path, script, capsys):
    assert script.main(["--audit-every", "5", "--num-cpus", "1", "--run-name", str(tmp_path / "run")]) == 2
    assert "background audits need a CPU of their own" in capsys.readouterr().err


def test_init_from_puts_the_modules_weights_into_the_learner_and_the_env_runner(ray_session, script):
    import torch

    from dsage_ray.agents.rllib import load_rllib_module

    args = script.parse_args(["--train-batch-size", "64", "--minibatch-size", "64", "--num-epochs", "1",
                              "--num-envs", "1", "--init-from", "rllib:ppo_maze"])
    algo = script.build_config(args).build_algo()
    try:
        expected = load_rllib_module("ppo_maze").state_dict()
        before = algo.get_module().state_dict()
        assert any(not torch.equal(before[k], v) for k, v in expected.items()), "fresh weights equal the shipped ones"
        script.load_initial_weights(algo, script.init_module_dir(args.init_from), args.init_from)
        for module in (algo.get_module(), algo.env_runner.module):
            loaded = module.state_dict()
            assert all(torch.equal(loaded[k], v) for k, v in expected.items())
    finally:
        algo.stop()


def test_an_init_from_that_does_not_fit_stops_with_one_line_and_writes_nothing(tmp_path, ray_session, script,
                                                                               capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(ray_session, "init", lambda **_: None)  # the session's cluster serves the script
    monkeypatch.setattr(ray_session, "shutdown", lambda: None)
    assert script.main(["--init-from", "ppo_maze", "--hidden", "32", "--run-name", "bad_init"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1].startswith("error: --init-from ppo_maze: its weights do not fit this run's module")
    assert "size mismatch" in err[-1]
    assert not (tmp_path / "tb_logs" / "bad_init").exists()
    assert script.main(["--init-from", "nosuch", "--run-name", "missing"]) == 2
    assert "error: --init-from nosuch: rllib checkpoint 'nosuch': not found" in capsys.readouterr().err
