"""``time_budget``: the run ends when it is reached, at a clean checkpoint, and resumes.

The clock of the runner and of the evaluations is replaced by one that advances one second per real
evaluation and stands still otherwise, so wall times are exact and the tests do not depend on the
machine's speed.
"""

from __future__ import annotations

import json
import time
import types

import pytest

from dsage_ray.config import RunConfig
from dsage_ray.core import evaluation as evaluation_module
from dsage_ray.core import runner as runner_module
from dsage_ray.core.checkpoint import CHECKPOINT_NAME, load_checkpoint
from dsage_ray.core.loop import run_locally
from dsage_ray.core.runner import DSAGE
from tests.fakes import SMALL_RUN, BitmapDomain


class EvaluationClock:
    """A ``perf_counter`` that advances one second per evaluation of a :class:`ClockedDomain`."""

    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


class ClockedDomain(BitmapDomain):
    """:class:`BitmapDomain` whose every evaluation takes one second of ``clock``."""

    def __init__(self, clock: EvaluationClock) -> None:
        super().__init__()
        self.clock = clock

    def evaluate(self, solution, seed):
        self.clock.now += 1.0
        return super().evaluate(solution, seed)


@pytest.fixture
def clock(monkeypatch) -> EvaluationClock:
    clock = EvaluationClock()
    fake_time = types.SimpleNamespace(perf_counter=clock, process_time=time.process_time)
    monkeypatch.setattr(runner_module, "time", fake_time)
    monkeypatch.setattr(evaluation_module, "time", fake_time)
    return clock


def config(**overrides) -> RunConfig:
    return RunConfig.build({**SMALL_RUN, "image_every": 100, **overrides})


def test_the_run_stops_inside_the_iteration_that_reaches_the_time_budget_and_resumes(tmp_path, clock):
    # The first outer iteration would evaluate n_rand = 40 levels, 1 s each; the budget of 30 s stops it after
    # the 30th (the level under way when time runs out finishes). The evaluation budget is 70.
    limited = config(time_budget=30.0)
    out = run_locally(limited, out_dir=tmp_path / "run", domain=ClockedDomain(clock), console=False)
    history = json.loads((out / "metrics.json").read_text())
    assert [row["evals"] for row in history] == [30]
    assert history[-1]["wall_time"] == 30.0 and history[-1]["evaluated_this_iteration"] == 30
    # A clean checkpoint of the stopped run, and its outputs.
    state = load_checkpoint(out / CHECKPOINT_NAME)
    assert state["evals"] == 30 and state["wall_time"] == 30.0 and len(state["dataset"]["levels"]) == 30
    assert (out / "archive.csv").exists()

    # Resumed with a larger time budget (the one key a resume may change): it continues where it stopped,
    # its clock too, to the evaluation budget.
    run_locally(config(time_budget=1_000.0), out_dir=out, resume=True, domain=ClockedDomain(clock), console=False)
    resumed = json.loads((out / "metrics.json").read_text())
    assert resumed[-1]["evals"] == 70 and resumed[0] == history[0]
    assert [row["wall_time"] for row in resumed] == [row["evals"] for row in resumed]  # 1 s per evaluation


def test_a_time_budget_never_cuts_a_batch_it_does_not_reach(tmp_path, clock):
    # Reached at the end of an iteration exactly (the first: 40 s), it stops there, as an unlimited run would.
    out = run_locally(config(time_budget=40.0), out_dir=tmp_path / "run", domain=ClockedDomain(clock), console=False)
    reference = DSAGE(config=config(), domain=ClockedDomain(clock))
    reference.step()
    assert json.loads((out / "metrics.json").read_text())[-1]["evals"] == reference.evals == 40


def test_a_time_budget_the_run_has_reached_refuses_another_step(clock):
    runner = DSAGE(config=config(time_budget=10.0), domain=ClockedDomain(clock))
    runner.step()
    assert runner.done and runner.out_of_time and runner.evals < runner.config.budget
    with pytest.raises(RuntimeError, match=r"the time budget \(10 s\) is spent"):
        runner.step()


def test_without_a_time_budget_only_evaluations_end_the_run(clock):
    runner = DSAGE(config=config(), domain=ClockedDomain(clock))
    runner.run()
    assert runner.evals == 70 and not runner.out_of_time and runner.wall_time == 70.0


def test_every_row_carries_cumulative_wall_and_cpu_time():
    # The real clocks: wall time covers at least the timed phases, CPU time grows with the work.
    runner = DSAGE(config=config(), domain=BitmapDomain())
    history = runner.run()
    walls = [row["wall_time"] for row in history]
    cpus = [row["cpu_time"] for row in history]
    assert walls == sorted(walls) and cpus == sorted(cpus) and cpus[-1] > 0
    assert walls[-1] >= sum(row["time_total"] for row in history)
    assert (runner.wall_time, runner.cpu_time) == (walls[-1], cpus[-1])


def test_state_dict_carries_the_clocks_and_a_resume_may_change_only_the_time_budget(clock):
    runner = DSAGE(config=config(time_budget=10.0), domain=ClockedDomain(clock))
    runner.step()
    state = runner.state_dict()
    later = DSAGE(config=config(time_budget=100.0), domain=ClockedDomain(clock))
    later.load_state_dict(state)
    assert later.wall_time == 10.0 and later.cpu_time == runner.cpu_time and not later.done
    with pytest.raises(ValueError, match="different config"):
        DSAGE(config=config(time_budget=100.0, seed=1), domain=ClockedDomain(clock)).load_state_dict(state)
    # A checkpoint from before the clocks were saved starts them at the resume.
    del state["wall_time"], state["cpu_time"]
    old = DSAGE(config=config(time_budget=10.0), domain=ClockedDomain(clock))
    old.load_state_dict(state)
    assert old.wall_time == 0.0 and old.cpu_time == 0.0 and not old.done


def test_tensorboard_logs_the_qd_score_against_whole_seconds_of_wall_time(tmp_path, clock):
    from tests.ray.helpers import tensorboard_scalars

    run_locally(config(), out_dir=tmp_path, domain=ClockedDomain(clock), console=False)
    history = json.loads((tmp_path / "metrics.json").read_text())
    scalars = tensorboard_scalars(tmp_path, prefix="dsage/")
    steps, values = zip(*scalars["dsage/qd_score_vs_wall_time"])
    assert list(steps) == [int(row["wall_time"]) for row in history]  # 1 s per evaluation: 40, 41, ...
    assert steps[0] == 40
    assert list(values) == pytest.approx([row["qd_score"] for row in history])
    assert {"dsage/wall_time", "dsage/cpu_time"} <= set(scalars)
