"""benchmarks/nominal_rule.py: the nominal check's false stops, counted on a training record."""

import numpy as np

from benchmarks.nominal_rule import false_stops, main


def test_steady_episodes_are_never_stopped_and_spread_ones_less_often_by_the_rule_than_by_the_margin_alone():
    rng = np.random.default_rng(0)
    assert false_stops(500.0, np.full(10, 500.0), episodes=10, draws=500, rng=rng) == (0.0, 0.0)
    # Episodes like the zoo's DQN lander: half crash, half land.
    spread = np.array([225.0, 62.0, 56.0, 187.0, 168.0, 34.0, 32.0, 47.0, 158.0, 168.0])
    relative, rule = false_stops(float(spread.mean()), spread, episodes=10, draws=4000, rng=rng)
    assert relative > 0.05 and rule < relative / 5


def test_it_prints_a_row_per_folder_and_episode_pool(tmp_path, capsys):
    folder = tmp_path / "ppo" / "Env-v0_1"
    folder.mkdir(parents=True)
    np.savez(folder / "evaluations.npz", results=np.full((3, 5), 7.0), timesteps=np.arange(3))
    assert main([str(tmp_path), "--draws", "50"]) == 0
    rows = [line for line in capsys.readouterr().out.splitlines() if line.startswith("ppo/Env-v0_1")]
    assert len(rows) == 2 and rows[0].split()[-2:] == ["0.0000", "0.0000"]
