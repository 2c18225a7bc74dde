"""The Tune Trainable: steps, checkpoints, restore after a crash, placement groups, resources."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from ray import tune

from dsage_ray.core.checkpoint import CHECKPOINT_NAME, load_checkpoint
from dsage_ray.core.runner import DSAGE
from dsage_ray.errors import InputError
from dsage_ray.ray.experiment import check_resources, run_experiment
from dsage_ray.ray.pool import PoolResourceError
from dsage_ray.ray.trainable import DSAGETrainable
from tests.fakes import BitmapDomain
from tests.ray.helpers import (CrashOnceTrainable, archive_snapshot, bitmap_domain, small_config,
                               tensorboard_scalars, tensorboard_tags)

pytestmark = pytest.mark.usefixtures("ray_session")


#: The restore tests compare archives only: no images (they cost seconds an iteration and change no archive),
#: and three outer iterations (the crash test's trial dies in the second).
RESTORED = {"image_every": 0, "budget": 90}


@pytest.fixture(scope="module")
def uninterrupted():
    """The reference: the same config run in-process without Ray."""
    runner = DSAGE(config=small_config(**RESTORED), domain=BitmapDomain())
    runner.run()
    return runner


def make_trainable(config) -> DSAGETrainable:
    return tune.with_parameters(DSAGETrainable, domain_factory=bitmap_domain)(config=config.to_flat())


def test_resource_request_has_a_bundle_per_simulator():
    request = DSAGETrainable.default_resource_request(small_config(ray__num_workers=3).to_flat())
    assert request.bundles == [{"CPU": 0.5}, {"CPU": 0.5}, {"CPU": 0.5}, {"CPU": 0.5}]


# Covered by the crash test below (save each step, restore, the uninterrupted archive); result keys: test_gridpath's
# ablate
@pytest.mark.slow
def test_step_save_restore_continues_exactly(tmp_path, uninterrupted):
    config = small_config(**RESTORED)
    first = make_trainable(config)
    try:
        result = first.train()
        assert {"evals", "qd_score", "coverage", "done"} <= set(result)
        assert result["evals"] == config.n_rand and not result["done"]
        first.save_checkpoint(str(tmp_path))
        assert (tmp_path / CHECKPOINT_NAME).exists()
    finally:
        first.stop()
    second = make_trainable(config)
    try:
        second.load_checkpoint(str(tmp_path))
        while not (result := second.train())["done"]:
            pass
        assert result["evals"] == config.budget
        assert archive_snapshot(second.runner.archive) == archive_snapshot(
            uninterrupted.archive)
    finally:
        second.stop()


def test_a_trial_killed_mid_run_restores_and_ends_with_the_uninterrupted_archive(tmp_path, uninterrupted):
    config = small_config(**RESTORED)
    assert len(uninterrupted.history) > 2  # the crash after step 2 comes before the last step
    trainable = tune.with_parameters(CrashOnceTrainable, domain_factory=bitmap_domain,
                                     crash_marker=str(tmp_path / "crashed"), crash_after=2)
    results = tune.Tuner(
        trainable,
        param_space=config.to_flat(),
        run_config=tune.RunConfig(
            name="crash", storage_path=str(tmp_path / "storage"), verbose=0,
            checkpoint_config=tune.CheckpointConfig(checkpoint_frequency=1, checkpoint_at_end=True),
            failure_config=tune.FailureConfig(max_failures=1),
        ),
    ).fit()
    assert (tmp_path / "crashed").exists(), "the trial never crashed: the test proves nothing"
    (result,) = results
    assert result.error is None
    assert result.metrics["done"] and result.metrics["evals"] == config.budget
    # Restored, not restarted: the first step after the crash is step 3 (iteration 2 was checkpointed).
    assert result.metrics["training_iteration"] == len(uninterrupted.history)
    assert result.metrics["pool_in_trial_placement_group"] == 1.0
    state = load_checkpoint(Path(result.checkpoint.path) / CHECKPOINT_NAME)
    assert archive_snapshot(state["archive"]) == archive_snapshot(uninterrupted.archive)
    history = result.metrics_dataframe
    assert list(history["training_iteration"]) == sorted(set(history["training_iteration"]))


def test_an_impossible_trial_request_fails_with_a_clear_message(tmp_path):
    config = small_config(ray__num_workers=8, ray__cpus_per_worker=1.0)
    with pytest.raises(PoolResourceError, match=r"ray.num_workers=8"):
        check_resources(config)


# 38 s: Tune runs with our TensorBoard scalars and images in tests/ray/test_ray_progress.py and test_mode_equality.py;
# this adds tune.run's API, a grid's labelled progress lines and the predicted-vs-true image.
@pytest.mark.slow
def test_tune_run_grid_writes_tensorboard_scalars_and_images(tmp_path, capsys):
    """``tune.run`` here; the Tuner path is exercised by the crash test and the ablation test."""

    # Images once, when the budget is spent: each set costs seconds, and once shows they reach TensorBoard.
    config = small_config(budget=70, image_every=100)
    space = {**config.to_flat(), "seed": tune.grid_search([0, 1])}
    for api in ("run",):
        experiment = run_experiment(space, name=f"tb_{api}", storage_path=tmp_path, api=api, max_failures=0,
                                    domain_factory=bitmap_domain, verbose=0)
        trial_dirs = sorted(trial.path for trial in experiment.trials)
        assert trial_dirs == sorted(p.parent for p in experiment.path.glob("*/params.json"))
        assert len(trial_dirs) == 2
        lines, finals = capsys.readouterr().out.splitlines(), []
        for trial_dir in trial_dirs:
            scalars, images = tensorboard_tags(trial_dir)
            # Tune's TensorBoard logger is off: its ray/tune/* copies (step = iteration) would duplicate ours.
            assert "dsage/qd_score" in scalars and not any(tag.startswith("ray/tune/") for tag in scalars)
            assert {"archive/heatmap", "surrogate/predicted_vs_true_measures", "levels/elite_0"} <= images
            assert (trial_dir / "archive.csv").exists() and (trial_dir / "metrics.json").exists()
            # Ours: the runner's metrics under dsage/, one point per outer iteration at its evaluation count
            # (the QD-score also within each iteration: qd.growth.growth_curve).
            history = json.loads((trial_dir / "metrics.json").read_text())
            ours = tensorboard_scalars(trial_dir, prefix="dsage/")
            assert {"dsage/qd_score", "dsage/coverage", "dsage/archive_size", "dsage/surrogate_loss",
                    "dsage/time_total", "dsage/new_cell_share"} <= set(ours)
            assert [step for step, _ in ours["dsage/archive_size"]] == [int(m["evals"]) for m in history]
            qd_score = dict(ours["dsage/qd_score"])
            assert len(qd_score) > len(history)
            assert [qd_score[int(m["evals"])] for m in history] == pytest.approx([m["qd_score"] for m in history])
            assert ours["dsage/qd_score"][-1][0] == config.budget
            # One progress line per result of each trial, labelled with its grid value.
            seed = json.loads((trial_dir / "params.json").read_text())["seed"]
            progress = [line for line in lines if line.startswith(f"seed={seed}  iter ")]
            assert len(progress) == len(history)
            assert progress[-1].startswith(f"seed={seed}  iter {len(history)}/{len(history)}  "
                                           f"evals {config.budget}/{config.budget}  ")
            assert "ETA done" in progress[-1]
            finals.append(progress[-1].rsplit("trials done ", 1)[1])
        assert sorted(finals) == ["1/2", "2/2"]  # a trial counts as done with its last result
        # What Tune stored is what was asked: resuming with the same config passes the resume check.
        from dsage_ray.ray.experiment import refuse_changed_config

        refuse_changed_config(experiment.path, space)


def test_a_resume_asking_for_another_config_is_refused_before_tune_starts(tmp_path):
    # Tune restores each trial with its own config: a new budget or key would be ignored without a word.
    experiment = tmp_path / "exp"
    for index, seed in enumerate((0, 1)):
        trial = experiment / f"DSAGETrainable_{index}"
        trial.mkdir(parents=True)
        (trial / "params.json").write_text(json.dumps({**small_config(time_budget=600.0, seed=seed).to_flat()}))
    space = small_config(time_budget=1200.0).to_flat()
    with pytest.raises(InputError, match=r"time_budget = 600, not 1200 .*--local"):
        run_experiment({**space, "seed": tune.grid_search([0, 1])}, name="exp", storage_path=tmp_path, resume=True,
                       domain_factory=bitmap_domain)
    with pytest.raises(InputError, match=r"budget = 120, not 90"):
        run_experiment(small_config(budget=90, time_budget=600.0).to_flat(), name="exp", storage_path=tmp_path,
                       resume=True, domain_factory=bitmap_domain)
    from dsage_ray.ray.experiment import refuse_changed_config

    seeds = {"seed": tune.grid_search([0, 1])}
    with pytest.raises(InputError, match=r"surrogate.epochs = 2, not 3"):
        refuse_changed_config(experiment, {**small_config(time_budget=600.0, surrogate__epochs=3).to_flat(), **seeds})
    # Nothing asked (time_budget 0) keeps the trials' own; the same config passes the check.
    refuse_changed_config(experiment, {**small_config(time_budget=0.0).to_flat(), **seeds})
    refuse_changed_config(experiment, {**small_config(time_budget=600.0).to_flat(), **seeds})
    # Only the keys the user gave are compared: a default that changed since leaves the trials their own.
    changed = {**small_config(time_budget=600.0, surrogate__epochs=3).to_flat(), **seeds}
    refuse_changed_config(experiment, changed, given={"budget", "seed", "time_budget"})
    with pytest.raises(InputError, match=r"surrogate.epochs = 2, not 3"):
        refuse_changed_config(experiment, changed, given={"surrogate.epochs"})
