"""The one run loop: callbacks, a checkpoint every outer iteration, exact resume, run folders."""

from __future__ import annotations

import json

import pytest

from dsage_ray.config import RunConfig
from dsage_ray.core.checkpoint import CHECKPOINT_NAME, load_checkpoint
from dsage_ray.core.loop import RunLoop, run_locally
from dsage_ray.core.runner import DSAGE
from dsage_ray.errors import InputError
from tests.fakes import SMALL_RUN, BitmapDomain


def config(**overrides) -> RunConfig:
    return RunConfig.build({**SMALL_RUN, "image_every": 100, **overrides})


class Recorder:
    """A loop callback that remembers what it saw."""

    def __init__(self) -> None:
        self.calls: list[tuple] = []

    def on_start(self, runner) -> None:
        self.calls.append(("start", runner.evals))

    def on_step(self, runner, metrics) -> None:
        self.calls.append(("step", int(metrics["evals"])))

    def close(self) -> None:
        self.calls.append(("close",))


def test_run_calls_back_checkpoints_every_iteration_and_writes_outputs_at_the_end(tmp_path, monkeypatch):
    run = config()
    runner = DSAGE(config=run, domain=BitmapDomain())
    recorder = Recorder()
    loop = RunLoop(runner=runner, out_dir=tmp_path, callbacks=[recorder])
    saved: list[int] = []
    monkeypatch.setattr(loop, "save", lambda path: saved.append(runner.outer_iteration))
    loop.run(checkpoint=tmp_path / CHECKPOINT_NAME)
    loop.close()
    iterations = len(runner.history)
    assert iterations >= 3
    assert saved == list(range(1, iterations + 1))
    assert recorder.calls == [("start", 0), *(("step", int(m["evals"])) for m in runner.history), ("close",)]
    assert (tmp_path / "archive.csv").exists() and (tmp_path / "metrics.json").exists()


def test_run_locally_resumed_after_a_crash_writes_the_uninterrupted_archive(tmp_path):
    run = config()
    reference = run_locally(run, out_dir=tmp_path / "reference", domain=BitmapDomain(), console=False)

    # An interrupted run: two iterations checkpointed, then the process "dies" (no outputs, no close).
    interrupted = tmp_path / "interrupted"
    loop = RunLoop(runner=DSAGE(config=run, domain=BitmapDomain()), out_dir=interrupted)
    for _ in range(2):
        loop.step()
    loop.save(interrupted / CHECKPOINT_NAME)
    loop.step()  # lost: not checkpointed
    assert not (interrupted / "archive.csv").exists()

    with pytest.raises(InputError, match="already holds a run: pass --resume"):
        run_locally(run, out_dir=interrupted, domain=BitmapDomain(), console=False)
    run_locally(run, out_dir=interrupted, resume=True, domain=BitmapDomain(), console=False)
    assert (interrupted / "archive.csv").read_bytes() == (reference / "archive.csv").read_bytes()
    assert json.loads((interrupted / "metrics.json").read_text())[-1]["qd_score"] == json.loads(
        (reference / "metrics.json").read_text())[-1]["qd_score"]
    assert load_checkpoint(interrupted / CHECKPOINT_NAME)["evals"] == run.budget


def test_resume_without_a_run_is_an_input_error(tmp_path):
    with pytest.raises(InputError, match="holds no run to resume"):
        run_locally(config(), out_dir=tmp_path, resume=True, domain=BitmapDomain(), console=False)


def test_console_progress_prints_a_line_per_iteration(tmp_path, capsys):
    run = config(budget=50, n_rand=40)
    run_locally(run, out_dir=tmp_path, domain=BitmapDomain())
    lines = [line for line in capsys.readouterr().out.splitlines() if line.startswith("iter ")]
    iterations = len(json.loads((tmp_path / "metrics.json").read_text()))
    assert len(lines) == iterations and lines[0].startswith("iter 1/~")
    assert lines[-1].startswith(f"iter {iterations}/{iterations}  evals 50/50") and lines[-1].endswith("ETA done")
