"""The progress line, its ETA, and the TensorBoard command printed at the end of a run."""

from __future__ import annotations

import os
import sys
from pathlib import Path

import pytest

from dsage_ray.core.progress import EvaluationRate, format_duration, progress_line
from dsage_ray.core.tensorboard_log import tensorboard_hint


@pytest.mark.parametrize("seconds, text", [(0, "0s"), (42.4, "42s"), (130, "2m10s"), (3600 + 5 * 60 + 59, "1h05m"),
                                           (float("inf"), "?")])
def test_format_duration(seconds, text):
    assert format_duration(seconds) == text


def test_progress_line_estimates_iterations_and_eta_from_the_evaluation_rate():
    metrics = {"outer_iteration": 3.0, "evals": 400.0, "evaluated_this_iteration": 160.0, "qd_score": 812.04,
               "coverage": 0.0312}
    line = progress_line(metrics, budget=2000, elapsed_s=130, evals_per_s=1600 / 390)
    # 1600 evaluations left at 160 per iteration: 10 more iterations; at 4.1/s: 6m30s.
    assert line == "iter 3/~13  evals 400/2000  qd_score 812.0  coverage 0.031  elapsed 2m10s  ETA 6m30s"


def test_progress_line_counts_down_the_time_budget_when_it_ends_the_run_first():
    metrics = {"outer_iteration": 3.0, "evals": 108.0, "evaluated_this_iteration": 4.0, "qd_score": 4.6,
               "coverage": 0.002, "wall_time": 30.0}
    line = progress_line(metrics, budget=100_000, elapsed_s=27, evals_per_s=3.0, time_budget=420)
    # 390 s left at 3 evaluations/s: 1,170 more, 293 iterations of 4.
    assert line == "iter 3/~296  evals 108/100000  qd_score 4.6  coverage 0.002  elapsed 27s  ETA 6m30s (time budget)"
    # The evaluation budget first: the usual estimate; past the time budget: done.
    assert progress_line({**metrics, "evals": 1990.0}, budget=2000, elapsed_s=27, evals_per_s=3.0,
                         time_budget=420).endswith("ETA 3s")
    assert progress_line({**metrics, "wall_time": 421.0}, budget=100_000, elapsed_s=421, evals_per_s=3.0,
                         time_budget=420).endswith("ETA done")


def test_progress_line_of_a_finished_run_and_of_an_unknown_rate():
    metrics = {"outer_iteration": 7.0, "evals": 150.0, "evaluated_this_iteration": 23.0, "qd_score": 1.0,
               "coverage": 0.5}
    assert progress_line(metrics, budget=150, elapsed_s=29, evals_per_s=5.0).startswith("iter 7/7  evals 150/150")
    assert progress_line(metrics, budget=150, elapsed_s=29, evals_per_s=5.0).endswith("ETA done")
    assert progress_line({**metrics, "evals": 100.0}, budget=150, elapsed_s=1, evals_per_s=0.0).endswith("ETA ?")


def test_evaluation_rate_leaves_the_cheap_first_iteration_out_once_a_later_one_is_seen():
    rate = EvaluationRate()
    assert rate.update(evals=100, running_s=2.0) == 50.0  # only the first iteration so far
    # 20 more evaluations in 8 s: 2.5/s, not the 120/10 = 12/s the whole run would suggest.
    assert rate.update(evals=120, running_s=10.0) == 2.5
    assert rate.update(evals=140, running_s=18.0) == 2.5


def test_tensorboard_hint_is_relative_below_the_working_directory(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("PATH", str(tmp_path / "empty"))  # no tensorboard on the PATH
    hint = tensorboard_hint(tmp_path / "tb_logs" / "run a")
    executable = Path(sys.executable).parent / "tensorboard"
    assert hint == f"{os.path.abspath(executable)} --logdir 'tb_logs/run a'"


def test_tensorboard_hint_uses_tensorboard_from_the_path(tmp_path, monkeypatch):
    bin_dir = tmp_path / "bin"
    bin_dir.mkdir()
    (bin_dir / "tensorboard").write_text("#!/bin/sh\n")
    (bin_dir / "tensorboard").chmod(0o755)
    monkeypatch.setenv("PATH", str(bin_dir))
    monkeypatch.chdir(bin_dir)
    assert tensorboard_hint(tmp_path / "runs") == f"tensorboard --logdir {tmp_path / 'runs'}"


def test_console_bars_close_when_their_pass_ends_except_the_run_long_evaluate_bar():
    from dsage_ray.core.progress import ConsoleProgress

    console = ConsoleProgress(budget=100)
    console.phase("holdout", 0, 10)
    console.phase("evaluate", 20, 100)
    console.phase("exploit", 3, 5)
    assert set(console._bars) == {"holdout", "evaluate", "exploit"}
    console.phase("holdout", 10, 10)
    console.phase("exploit", 5, 5)
    assert set(console._bars) == {"evaluate"}  # finished passes are gone, not redrawn with a running clock
    console.phase("exploit", 1, 5)  # the next inner loop gets a fresh bar
    assert console._bars["exploit"].n == 1
    console.phase("evaluate", 100, 100)
    assert set(console._bars) == {"evaluate", "exploit"}
    console.close()
    assert not console._bars


def test_the_console_prints_what_search_auto_chose_once_with_its_numbers(capsys):
    from types import SimpleNamespace

    from dsage_ray.config import RunConfig
    from dsage_ray.core.auto_search import choose_search
    from dsage_ray.core.progress import ConsoleProgress

    run = SimpleNamespace(config=RunConfig.build({"domain": "maze"}), evals=0)
    row = {"outer_iteration": 2.0, "evals": 300.0, "evaluated_this_iteration": 150.0, "qd_score": 1.0, "coverage": 0.1}
    choice = choose_search([{"time_evaluate": 1.0, "evaluated_this_iteration": 100.0}], surrogate_seconds=50.0,
                           picks=20, probe_seconds=0.0, probed=8, direct_variant="map_elites")
    console = ConsoleProgress(budget=1000)
    console.on_step(run, row)
    console.on_step(run, {**row, **choice.metrics()})
    lines = capsys.readouterr().out.splitlines()
    assert [line for line in lines if line.startswith("search auto")] == [
        "search auto: continuing with map_elites on the same archive (a pick costs 2.5 s with the surrogate's time, "
        "a random level 0.01 s: 250.00×; break-even 3×)"]
