"""benchmarks/bench_elite_mutants.py on a real (tiny) Maze run."""

from __future__ import annotations

import re
import sys
from pathlib import Path

import pytest

BENCHMARKS = Path(__file__).resolve().parents[2] / "benchmarks"
sys.path.insert(0, str(BENCHMARKS))

import bench_elite_mutants as bench  # noqa: E402


def tiny_run(tmp_path: Path, **overrides) -> Path:
    from dsage_ray.config import RunConfig
    from dsage_ray.core.loop import run_locally

    # One random iteration of 30 levels: the benchmark reads only the run's ground-truth archive.
    config = RunConfig.build({"domain": "maze", "preset": "tiny", "maze.agent": "builtin:wall_follower",
                              "maze.episodes": 2, "budget": 30, "n_rand": 30, "surrogate.epochs": 1,
                              "qd.exploit_iterations": 2, "image_every": 1000, **overrides})
    return run_locally(config, out_dir=tmp_path / "run", console=False)


def test_each_pool_of_parents_gets_a_line_of_its_mutants(tmp_path, capsys):
    run = tiny_run(tmp_path, **{"maze.objective": "failure_rate"})
    assert bench.main([str(run), "--levels", "6"]) == 0
    printed = capsys.readouterr().out
    assert re.search(r"\d+ elites, best objective [\d.]+ \(\d+ elites\), top share 0.05 \(\d+ elites\); 6 mutants "
                     r"per pool, map_elites mutation", printed), printed
    for pool in ("best", "top share", "uniform"):
        assert re.search(rf"{pool}: 6 mutants, mean objective [\d.]+, \d+% at the best .*% in a new cell, "
                         r"[\d.]+ CPU s per evaluation", printed), (pool, printed)


def test_a_folder_without_a_checkpoint_is_refused(tmp_path):
    with pytest.raises(SystemExit, match="no checkpoint.dsage"):
        bench.main([str(tmp_path)])
