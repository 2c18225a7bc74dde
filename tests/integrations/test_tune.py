"""``dsage_ray.integrations.tune.AuditCheckpointsCallback``: every N-th checkpoint of each trial, and the fault rule."""

from __future__ import annotations

import dataclasses
import logging
import pickle
import time
from pathlib import Path

import pytest

from tests.integrations.conftest import FakeSeries

AuditCheckpointsCallback = pytest.importorskip("dsage_ray.integrations.tune").AuditCheckpointsCallback


@dataclasses.dataclass
class FakeTrial:
    trial_id: str
    local_path: str
    last_result: dict = dataclasses.field(default_factory=dict)


@dataclasses.dataclass
class FakeCheckpoint:
    path: str


def series_factory(made: dict, **kwargs):
    def factory(**settings):
        made[settings["out_dir"]] = series = FakeSeries(**settings, **kwargs)
        return series
    return factory


def checkpoint(callback, trial, tmp_path: Path, n: int) -> Path:
    path = tmp_path / trial.trial_id / f"checkpoint_{n:06d}"
    path.mkdir(parents=True)
    trial.last_result = {"training_iteration": 10 * n, "env_runners": {"num_env_steps_sampled_lifetime": 4000 * n}}
    callback.on_checkpoint(iteration=n, trials=[trial], trial=trial, checkpoint=FakeCheckpoint(str(path)))
    return path


def test_every_nth_checkpoint_of_each_trial_is_audited(tmp_path):
    made: dict = {}
    callback = AuditCheckpointsCallback(out_dir=tmp_path / "audits", audit_every=3, tensorboard=False, background=False,
                                        series=series_factory(made), spec_from_checkpoint=lambda p: f"dcd:{p}/model.tar")
    a, b = FakeTrial("a", str(tmp_path / "a")), FakeTrial("b", str(tmp_path / "b"))
    for n in range(1, 8):
        checkpoint(callback, a, tmp_path, n)
        if n <= 3:
            checkpoint(callback, b, tmp_path, n)
    series_a, series_b = made[tmp_path / "audits" / "a" / "audit_series"], made[tmp_path / "audits" / "b" / "audit_series"]
    assert series_a.calls == [(f"dcd:{tmp_path}/a/checkpoint_000003/model.tar", "iter_30", 12000),
                              (f"dcd:{tmp_path}/a/checkpoint_000006/model.tar", "iter_60", 24000)]
    assert [label for _, label, _ in series_b.calls] == ["iter_30"]
    assert [(t, label) for t, label, _ in callback.audits] == [("a", "iter_30"), ("b", "iter_30"), ("a", "iter_60")]
    # Tune saves and restores callback state with the experiment: the counts go on after a restore.
    from ray import cloudpickle

    assert cloudpickle.loads(cloudpickle.dumps(callback))._auditors == {}  # Tune pickles its callbacks
    restored = AuditCheckpointsCallback(out_dir=tmp_path / "audits", audit_every=3)
    restored.set_state(pickle.loads(pickle.dumps(callback.get_state())))
    assert restored.counts == {"a": 7, "b": 3}


def test_the_default_spec_is_a_copy_of_the_rllib_module(tmp_path):
    made: dict = {}
    callback = AuditCheckpointsCallback(out_dir=tmp_path / "audits", audit_every=1, tensorboard=False,
                                        series=series_factory(made), background=False)
    trial = FakeTrial("t", str(tmp_path / "t"))
    path = tmp_path / "t" / "checkpoint_000001"
    module = path / "learner_group" / "learner" / "rl_module" / "default_policy"
    module.mkdir(parents=True)
    (module / "class_and_ctor_args.pkl").write_bytes(b"x")
    trial.last_result = {"training_iteration": 4}
    callback.on_checkpoint(iteration=1, trials=[trial], trial=trial, checkpoint=FakeCheckpoint(str(path)))
    copy = (tmp_path / "audits" / "t" / "checkpoints" / "iter_4").resolve()
    ((spec, label, step),) = made[tmp_path / "audits" / "t" / "audit_series"].calls
    assert (spec, label, step) == (f"rllib:{copy}", "iter_4", 4)  # no env steps reported: the iteration
    assert (copy / "class_and_ctor_args.pkl").read_bytes() == b"x"


def test_a_failing_audit_logs_one_warning_and_the_experiment_goes_on(tmp_path, caplog):
    made: dict = {}
    callback = AuditCheckpointsCallback(out_dir=tmp_path / "audits", audit_every=1, tensorboard=False,
                                        series=series_factory(made, fail=ConnectionError("actor died")),
                                        background=False)
    trial = FakeTrial("t", str(tmp_path / "t"))
    with caplog.at_level(logging.WARNING):
        checkpoint(callback, trial, tmp_path, 1)  # an empty folder: not an RLlib checkpoint
        callback.spec_from_checkpoint = lambda p: "rllib:somewhere"
        checkpoint(callback, trial, tmp_path, 2)  # the series raises
    lines = [r.getMessage() for r in caplog.records if r.levelno == logging.WARNING]
    assert len(lines) == 2
    assert lines[0].startswith("audit of iter_10 skipped: AgentError: rllib checkpoint")
    assert lines[1] == "audit of iter_20 skipped: ConnectionError: actor died"
    assert [record for _, _, record in callback.audits] == [None, None]


def test_scalars_go_to_the_trial_folder(tmp_path):
    made: dict = {}
    callback = AuditCheckpointsCallback(out_dir=tmp_path / "audits", audit_every=1, series=series_factory(made),
                                        spec_from_checkpoint=lambda p: "builtin:random", background=False)
    trial = FakeTrial("t", str(tmp_path / "trial_dir"))
    checkpoint(callback, trial, tmp_path, 1)
    assert list((tmp_path / "trial_dir").glob("events.out.tfevents.*"))


def test_background_audits_end_with_the_experiment(tmp_path, ray_session):
    callback = AuditCheckpointsCallback(out_dir=tmp_path / "audits", audit_every=2, series=FakeSeries,
                                        spec_from_checkpoint=lambda p: f"dcd:{p}", tensorboard=False)
    trial = FakeTrial("t", str(tmp_path / "t"))
    for n in range(1, 5):
        checkpoint(callback, trial, tmp_path, n)
        if n == 2:  # Tune's loop polls the running audit at every step until it has ended
            deadline = time.monotonic() + 60
            while not callback.audits and time.monotonic() < deadline:
                callback.on_step_begin(iteration=n, trials=[trial])
                time.sleep(0.1)
    callback.on_experiment_end(trials=[trial])  # waits for the audit of the 4th
    assert [(label, record.agent, record.step) for _, label, record in callback.audits] == [
        ("iter_20", f"dcd:{tmp_path}/t/checkpoint_000002", 8000), ("iter_40", f"dcd:{tmp_path}/t/checkpoint_000004", 16000)]
