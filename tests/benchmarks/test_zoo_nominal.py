"""``benchmarks/zoo_nominal.py``: one row per run folder, the zoo's figure beside the one played here."""

import sys

import pytest

from benchmarks import zoo_nominal
from tests.agents.test_sb3 import make_run_folder

pytest.importorskip("stable_baselines3")


def test_a_row_per_folder_with_what_was_applied(tmp_path, monkeypatch, capsys):
    make_run_folder(tmp_path)
    broken = tmp_path / "ppo" / "Pendulum-v1_1"
    (broken / "Pendulum-v1").mkdir(parents=True)
    (broken / "Pendulum-v1" / "config.yml").write_text("{}\n")
    (broken / "Pendulum-v1.zip").write_bytes(b"")
    monkeypatch.setattr(sys, "argv", ["zoo_nominal.py", str(tmp_path), "--episodes", "2"])
    zoo_nominal.main()
    rows = [line for line in capsys.readouterr().out.splitlines() if line.startswith("| ppo/")]
    assert len(rows) == 2
    cartpole, pendulum = sorted(rows)
    assert "| CartPole-v1 | 52.0 |" in cartpole and "VecNormalize, 2 frames, 1 wrapper(s)" in cartpole
    assert "not played:" in pendulum and "an empty file" in pendulum


def test_renamed_versions():
    assert zoo_nominal.nominal_env("LunarLanderContinuous-v2") == ("LunarLander-v3", {"continuous": True})
    assert zoo_nominal.nominal_env("CartPole-v1") == ("CartPole-v1", {})
