"""benchmarks/bench_cost_prediction.py on a real (tiny) expected-gain run that records the Maze's work counts."""

from __future__ import annotations

import re
import sys
from pathlib import Path

import pytest

BENCHMARKS = Path(__file__).resolve().parents[2] / "benchmarks"
sys.path.insert(0, str(BENCHMARKS))

import bench_cost_prediction as bench  # noqa: E402


def tiny_run(tmp_path: Path, **overrides) -> Path:
    from dsage_ray.config import RunConfig
    from dsage_ray.core.loop import run_locally

    config = RunConfig.build({"domain": "maze", "preset": "tiny", "maze.agent": "builtin:wall_follower",
                              "maze.episodes": 2, "budget": 60, "n_rand": 30, "surrogate.epochs": 1,
                              "qd.exploit_iterations": 2, "image_every": 1000, **overrides})
    return run_locally(config, out_dir=tmp_path / "run", console=False)


def test_the_trained_on_levels_and_the_unseen_picks_each_get_a_line(tmp_path, capsys):
    import json

    run = tiny_run(tmp_path, variant="dsage_gain", **{"selection.cost_measure": "steps", "selection.min_gain": 0.0})
    assert bench.main([str(run)]) == 0
    printed = capsys.readouterr().out
    last = json.loads((run / "metrics.json").read_text())[-1]
    unseen = int(last["evaluated_this_iteration"] - last.get("failed_evals", 0))
    assert f"the last {unseen} were picked" in printed
    trained = re.search(r"trained on\s+\((\d+)\): mean [\d,]+, \d+% above", printed)
    picks = re.search(rf"unseen picks \({unseen}\): mean [\d,]+, \d+% above .*correlation with the predicted "
                      r"objective .*num_walls .*mean_path_length .*occupancy sum", printed)
    assert trained and picks, printed
    assert int(trained.group(1)) + unseen == last["evals"] - last.get("failed_evals", 0)


def test_a_run_without_work_counts_is_refused_by_name(tmp_path, capsys):
    run = tiny_run(tmp_path, variant="dsage_gain", budget=30)  # only the random levels: nothing picked yet
    with pytest.raises(SystemExit):
        bench.main([str(run)])
    assert f"{run} recorded no work counts" in capsys.readouterr().err
