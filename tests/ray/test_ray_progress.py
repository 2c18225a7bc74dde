"""What a run through Tune prints and where it points: progress lines, no Ray TensorBoard hint, our command last.

A local run's lines are ``tests/test_api.py``'s (its command-line run)."""

from __future__ import annotations

import json
import os
import shlex
from pathlib import Path

import pytest

import dsage_ray
from dsage_ray.cli import main
from dsage_ray.core.tensorboard_log import tensorboard_hint
from tests.ray.helpers import tensorboard_tags

MAZE_CONFIG = "experiments/configs/maze_dsage.toml"
MAZE_OVERRIDES = {"maze.agent": "builtin:wall_follower", "budget": 30, "n_rand": 20, "selection.count": 10,
                  "maze.episodes": 1}
#: A maze run through the real CLI, as small as it gets: a few outer iterations.
MAZE_RUN = ["run", MAZE_CONFIG, "--preset", "tiny", *(f"--set={key}={value}" for key, value in MAZE_OVERRIDES.items())]


def _pointer_lines(stdout: str) -> tuple[str, str]:
    *_, folder_line, tensorboard_line = stdout.rstrip().splitlines()
    return folder_line, tensorboard_line


def _logdir(tensorboard_line: str) -> Path:
    prefix = "open it in TensorBoard: "
    assert tensorboard_line.startswith(prefix)
    words = shlex.split(tensorboard_line[len(prefix):])
    assert words[0].endswith("tensorboard") and words[1] == "--logdir"
    return Path(words[2])


@pytest.mark.usefixtures("ray_session")
def test_run_through_tune_prints_our_progress_lines_not_tunes_hint_and_ends_with_the_run_folder_and_tensorboard(
        tmp_path, monkeypatch, capfd):
    # One Tune run for what it prints, where it points and where it is stored: a Tune start costs more than the run.
    # It is stored at a file URI outside the working directory, written and read back through Tune's storage layer.
    # The conftest selects the legacy engine for every test; a user's shell does not.
    monkeypatch.delenv("RAY_AIR_NEW_OUTPUT", raising=False)
    uri = f"file://{tmp_path}/storage"
    assert main([*MAZE_RUN, "--out", uri]) == 0
    captured = capfd.readouterr()
    output = captured.out + captured.err
    # Tune's new console output prints its own TensorBoard hint and its periodic status table: only ours is left.
    assert output.count("tensorboard --logdir") == 1
    assert "Trial status" not in output
    lines = [line for line in captured.out.splitlines() if line.startswith("iter ")]
    assert lines[0].startswith("iter 1/~") and lines[-1].startswith(f"iter {len(lines)}/{len(lines)}  evals 30/30")
    assert "RAY_AIR_NEW_OUTPUT" not in os.environ  # set for the run only
    folder_line, tensorboard_line = _pointer_lines(captured.out)
    run_dir = Path(folder_line.removeprefix("run folder: "))
    assert run_dir.is_relative_to(tmp_path / "storage" / "maze_dsage") and (run_dir / "metrics.json").exists()
    assert not Path("file:").exists()  # the URI was not taken for a relative folder of the working directory
    assert tensorboard_line == f"open it in TensorBoard: {tensorboard_hint(run_dir)}"
    # The folder it names holds the images and our scalars, without Tune's copies against the iteration.
    scalars, images = tensorboard_tags(_logdir(tensorboard_line).resolve())
    assert {"archive/heatmap", "levels/elite_0"} <= images
    assert "dsage/qd_score" in scalars and not any(tag.startswith("ray/tune/") for tag in scalars)
    # The same URI resumes it: the finished trial is read back, not run again.
    again = dsage_ray.run(MAZE_CONFIG, preset="tiny", overrides=MAZE_OVERRIDES, out=uri, resume=True)
    assert again.path == run_dir and again.checkpoint.is_file() and len(again.archive) > 0
    assert again.metrics == json.loads((run_dir / "metrics.json").read_text())


def test_trials_done_counts_a_trial_that_said_done_while_tune_still_shows_it_running(capsys):
    from types import SimpleNamespace

    from dsage_ray.ray.progress import ProgressLines

    def trial(trial_id: str, seed: int):
        return SimpleNamespace(trial_id=trial_id, status="RUNNING", evaluated_params={"seed": seed},
                               error_file=None)

    first, second = trial("a", 0), trial("b", 1)
    callback = ProgressLines()
    callback.setup()
    last = {"outer_iteration": 2, "evals": 50, "budget": 50, "time_total_s": 5.0, "qd_score": 1.0, "coverage": 0.1,
            "done": True}
    # Both trials' last results arrive before Tune marks either TERMINATED (seen in CI).
    callback.on_trial_result(iteration=1, trials=[first, second], trial=first, result=last)
    callback.on_trial_result(iteration=2, trials=[first, second], trial=second, result=last)
    finals = [line.rsplit("trials done ", 1)[1] for line in capsys.readouterr().out.splitlines()]
    assert finals == ["1/2", "2/2"]
