"""``dsage_ray.integrations.rllib.AuditCallback``: when it audits, what it records, and that no audit stops training.

Most tests audit in this process with a fake series object; the background ones (a Ray actor per series)
use the session's Ray cluster.
"""

from __future__ import annotations

import copy
import functools
import logging
import os
import pickle
import time
from pathlib import Path

import pytest

from tests.integrations.conftest import FakeRecord, FakeSeries, FakeWriter

rllib_integration = pytest.importorskip("dsage_ray.integrations.rllib")
AuditCallback, finish_audits = rllib_integration.AuditCallback, rllib_integration.finish_audits


class FakeModule:
    def save_to_path(self, path: str) -> str:
        Path(path).mkdir(parents=True)
        (Path(path) / "module_state.pkl").write_bytes(b"weights")
        return path


class FakeAlgorithm:
    """What the callback touches of an Algorithm: ``get_module``."""

    def __init__(self, *, broken: bool = False) -> None:
        self.broken = broken

    def get_module(self, policy: str):
        if self.broken:
            raise OSError("disk full")
        return FakeModule()


def result(iteration: int, steps_per_iteration: int = 1000) -> dict:
    return {"training_iteration": iteration,
            "env_runners": {"num_env_steps_sampled_lifetime": iteration * steps_per_iteration}}


def train(callback, iterations: int, algorithm=None) -> list[dict]:
    algorithm = algorithm or FakeAlgorithm()
    results = []
    for i in range(1, iterations + 1):
        results.append(result(i))
        callback.on_train_result(algorithm=algorithm, metrics_logger=None, result=results[-1])
    return results


def audit_warnings(caplog) -> list[str]:
    return [r.getMessage() for r in caplog.records if r.levelno == logging.WARNING and "audit of" in r.getMessage()]


def test_audits_every_n_iterations_with_module_checkpoint_label_and_env_steps(tmp_path):
    series, writer = FakeSeries(), FakeWriter()
    callback = AuditCallback(audit_every=3, out_dir=tmp_path, series=series, writer=writer)
    results = train(callback, 7)
    assert [(label, step) for _, label, step in series.calls] == [("iter_3", 3000), ("iter_6", 6000)]
    assert series.calls[0][0] == f"rllib:{(tmp_path / 'checkpoints' / 'iter_3').resolve()}"
    assert (tmp_path / "checkpoints" / "iter_6" / "module_state.pkl").is_file()
    assert [("audit" in r) for r in results] == [False, False, True, False, False, True, False]
    assert results[2]["audit"] == {"new_failures": 2.0, "wall_time": 0.01, "suite_success_rate": 0.5,
                                   "checkpoint_iteration": 3}
    assert ("audit/suite_success_rate", 0.5, 6000) in writer.scalars
    assert {tag for tag, _, _ in writer.scalars} == {"audit/new_failures", "audit/wall_time",
                                                      "audit/suite_success_rate"}


def test_default_series_is_built_lazily_in_the_series_folder(tmp_path):
    built = []

    def factory(**settings):
        built.append(settings)
        return FakeSeries(**settings)

    callback = AuditCallback(audit_every=2, out_dir=tmp_path, series=factory, audit_budget=40, background=False)
    train(callback, 1)
    assert not built  # constructing and non-audit iterations build nothing (RLlib also builds one per env runner)
    train(callback, 4)
    assert len(built) == 1
    assert built[0]["out_dir"] == tmp_path / "audit_series" and built[0]["budget"] == 40
    assert built[0]["preset"] == "tiny" and built[0]["local"] is True
    assert built[0]["overrides"]["n_rand"] == 20


def test_a_raising_audit_logs_one_warning_and_training_goes_on(tmp_path, caplog):
    series = FakeSeries(fail=RuntimeError("The actor died unexpectedly before finishing this task.\nmore"))
    callback = AuditCallback(audit_every=2, out_dir=tmp_path, series=series)
    with caplog.at_level(logging.WARNING):
        results = train(callback, 4)
    assert audit_warnings(caplog) == [
        "audit of iter_2 skipped: RuntimeError: The actor died unexpectedly before finishing this task.",
        "audit of iter_4 skipped: RuntimeError: The actor died unexpectedly before finishing this task."]
    assert len(series.calls) == 2 and not any("audit" in r for r in results)


def test_an_unsaveable_checkpoint_logs_one_warning(tmp_path, caplog):
    series = FakeSeries()
    callback = AuditCallback(audit_every=1, out_dir=tmp_path, series=series)
    with caplog.at_level(logging.WARNING):
        train(callback, 1, FakeAlgorithm(broken=True))
    assert audit_warnings(caplog) == ["audit of iter_1 skipped: OSError: disk full"]
    assert not series.calls


def test_an_unreadable_checkpoint_logs_one_warning(tmp_path, caplog):
    series = FakeSeries(load=True)  # loads the spec: a module folder without RLlib's files does not load
    callback = AuditCallback(audit_every=1, out_dir=tmp_path, series=series)
    with caplog.at_level(logging.WARNING):
        train(callback, 1)
    (line,) = audit_warnings(caplog)
    assert line.startswith("audit of iter_1 skipped: AgentError: rllib checkpoint") and "not an RLlib checkpoint" in line


def test_a_record_with_an_error_logs_one_warning_and_keeps_its_numbers(tmp_path, caplog):
    writer = FakeWriter()
    callback = AuditCallback(audit_every=1, out_dir=tmp_path, writer=writer,
                             series=FakeSeries(error="TrialFailed: the search failed"))
    with caplog.at_level(logging.WARNING):
        (out,) = train(callback, 1)
    assert audit_warnings(caplog) == ["audit of iter_1 skipped: TrialFailed: the search failed"]
    assert out["audit"] == {"new_failures": 2.0, "wall_time": 0.01, "checkpoint_iteration": 1}
    assert len(writer.scalars) == 2


def test_configured_is_what_rllib_accepts_and_survives_copies(tmp_path):
    from ray.rllib.algorithms.ppo import PPOConfig

    writer = FakeWriter()
    factory = AuditCallback.configured(audit_every=5, out_dir=tmp_path, writer=writer)
    config = PPOConfig().callbacks(factory)
    built = copy.deepcopy(config).callbacks_class()
    assert isinstance(built, AuditCallback) and built.audit_every == 5 and built.auditor.writer is writer
    # Pickled (for remote env runners) a writer or series that cannot be pickled is dropped, not an error.
    writer.lock = __import__("threading").Lock()
    remote = pickle.loads(pickle.dumps(factory))()
    assert remote.audit_every == 5 and remote.auditor.writer is None
    series = FakeSeries()
    series.lock = writer.lock
    remote = pickle.loads(pickle.dumps(AuditCallback.configured(audit_every=1, out_dir=tmp_path, series=series)))()
    assert not remote.auditor.background and type(remote.auditor.series).__name__ == "_NoSeries"
    with pytest.raises(ValueError, match="audit_every"):
        AuditCallback.configured(audit_every=0, out_dir=tmp_path)
    with pytest.raises(ValueError, match="out_dir"):
        AuditCallback.configured(audit_every=1)
    with pytest.raises(ValueError, match="not a series object"):
        AuditCallback.configured(audit_every=1, out_dir=tmp_path, series=FakeSeries(), background=True)


def test_a_real_ppo_training_audits_a_loadable_module_in_the_background(tmp_path, ray_session, script, caplog):
    """Three tiny PPO iterations of the project's training config with the callback: the audit of
    iteration 2 runs in a Ray actor on a module checkpoint that the ``rllib:`` loader loads, at the lifetime
    env steps, and its numbers reach the writer once it has ended."""
    args = script.parse_args(["--train-batch-size", "64", "--minibatch-size", "64", "--num-epochs", "1",
                              "--num-envs", "1", "--audit-every", "2", "--seed", "3"])
    writer = FakeWriter()
    config = script.build_config(args).callbacks(AuditCallback.configured(
        audit_every=args.audit_every, out_dir=tmp_path, series=functools.partial(FakeSeries, load=True),
        writer=writer))
    algo = config.build_algo()
    try:
        with caplog.at_level(logging.WARNING):
            results = [algo.train() for _ in range(3)]
            audits = [a for a in [*algo.callbacks[0].audits] if a[1] is not None] if isinstance(algo.callbacks, list) \
                else list(algo.callbacks.audits)
            audits += finish_audits(algo, timeout=120)
    finally:
        algo.stop()
    assert not [r for r in caplog.records if "audit of" in r.getMessage()]
    ((iteration, record, waited),) = audits
    steps = int(results[1]["env_runners"]["num_env_steps_sampled_lifetime"])
    assert (record.agent, record.label, record.step) == (
        f"rllib:{(tmp_path / 'checkpoints' / 'iter_2').resolve()}", "iter_2", steps)
    assert iteration == 2 and steps >= 128 and waited < 30
    assert {s for _, _, s in writer.scalars} == {steps}


class DiesOnce(FakeSeries):
    """The actor's process exits at its first audit; a new actor (the marker file exists) audits."""

    def audit(self, agent, *, label=None, step=None):
        marker = Path(self.settings["out_dir"]).parent / "died"
        if not marker.exists():
            marker.parent.mkdir(parents=True, exist_ok=True)
            marker.touch()
            os._exit(1)
        return super().audit(agent, label=label, step=step)


class Slow(FakeSeries):
    def audit(self, agent, *, label=None, step=None):
        time.sleep(3)
        return super().audit(agent, label=label, step=step)


def test_a_dead_audit_actor_logs_one_warning_and_the_next_audit_gets_a_new_one(tmp_path, ray_session, caplog):
    callback = AuditCallback(audit_every=1, out_dir=tmp_path, series=DiesOnce)
    assert callback.auditor.background
    with caplog.at_level(logging.WARNING):
        train(callback, 1)
        callback.finish(timeout=60)
        callback.on_train_result(algorithm=FakeAlgorithm(), result=result(2))  # a new actor
        callback.finish(timeout=60)
    (line,) = [r.getMessage() for r in caplog.records if "audit of" in r.getMessage()]
    assert line == "audit of iter_1 skipped: ActorDiedError: The actor died unexpectedly before finishing this task."
    assert [(i, r is None) for i, r, _ in callback.audits] == [(1, True), (2, False)]


def test_an_audit_due_while_one_runs_is_skipped_with_a_warning(tmp_path, ray_session, caplog):
    callback = AuditCallback(audit_every=1, out_dir=tmp_path, series=Slow)
    with caplog.at_level(logging.WARNING):
        results = train(callback, 2)
        callback.finish(timeout=60)
    assert [r.getMessage() for r in caplog.records if "audit of" in r.getMessage()] == [
        "audit of iter_2 skipped: the audit of iter_1 is still running (or waiting for a CPU); audit less often"]
    assert not any("audit" in r for r in results)  # the audit ended after the last iteration
    assert [(i, type(r)) for i, r, _ in callback.audits] == [(1, FakeRecord)]


def test_an_audit_leaves_the_global_random_states_as_they_were(tmp_path):
    import random

    import numpy as np
    import torch

    class Greedy(FakeSeries):
        def audit(self, agent, *, label=None, step=None):
            random.random(), np.random.random(), torch.rand(3)
            torch.set_num_threads(2)
            return super().audit(agent, label=label, step=step)

    callback = AuditCallback(audit_every=1, out_dir=tmp_path, series=Greedy())
    for seeded in (True, False):
        random.seed(1), np.random.seed(1), torch.manual_seed(1)
        threads = torch.get_num_threads()
        if seeded:
            train(callback, 1)
        draws = (random.random(), np.random.random(), torch.rand(1).item())
        assert torch.get_num_threads() == threads
        if seeded:
            with_audit = draws
    assert draws == with_audit
