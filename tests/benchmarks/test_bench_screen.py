"""benchmarks/bench_screen.py on a tiny dataset of a built-in agent."""

from __future__ import annotations

import re
import sys
from pathlib import Path

import numpy as np

BENCHMARKS = Path(__file__).resolve().parents[2] / "benchmarks"
sys.path.insert(0, str(BENCHMARKS))

import bench_screen as bench  # noqa: E402
from maze_dataset import MazeData, save  # noqa: E402

from dsage_ray.domains.maze.domain import MazeDomain  # noqa: E402
from dsage_ray.domains.maze.plugin import MazeConfig  # noqa: E402


def test_it_scores_each_episode_count_against_the_datasets_path_length(tmp_path, capsys):
    domain = MazeDomain(config=MazeConfig(height=6, width=6, agent="builtin:random", episodes=20))
    rng = np.random.default_rng(0)
    walls = (rng.random((12, 6, 6)) < 0.25)
    measures = np.array([[domain.evaluate(w.ravel().astype(np.int8), seed=i).info["mean_path_length"]]
                         for i, w in enumerate(walls)], dtype=np.float32)
    path = save(MazeData(walls, measures, ("mean_path_length",)), tmp_path / "tiny.npz")
    out = bench.main(["--data", str(path), "--agent", "builtin:random", "--episodes", "1,5", "--levels", "10",
                      "--full", "3", "--full-episodes", "20", "--precision", "fp32,bf16"])
    printed = capsys.readouterr().out
    assert re.search(r"10 levels of .*tiny.npz \(\d+ valid\), agent builtin:random", printed), printed
    for k in (1, 5):
        assert re.search(rf"screen, {k} episode\(s\), fp32: Spearman ρ -?[\d.]+, MAE [\d.]+ steps, [\d.]+ ms per level",
                         printed), printed
        assert re.search(rf"screen_{k}: a screened level costs [\d.]+% of an evaluation", printed), printed
        assert out[f"screen_{k}"]["mae"] >= 0 and -1 <= out[f"screen_{k}"]["rho"] <= 1
        # The random agent has no reduced-precision copy: its bf16 screen is the same screen.
        assert re.search(rf"screen_{k}_bf16: a screened level costs [\d.]+% of an evaluation", printed), printed
        assert out[f"screen_{k}_bf16"]["rho"] == out[f"screen_{k}"]["rho"]
    assert "a full evaluation (20 episodes, one level at a time, 3 levels)" in printed
