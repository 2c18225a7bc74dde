"""Running DSAGE trials with Ray Tune: one run, or a grid of variants × seeds (the paper's ablations).

Both of Tune's entry points are supported and share everything but the call itself:

* ``tune.run(...)`` — the classic function API;
* ``tune.Tuner(...).fit()`` — the current API, resumable with ``Tuner.restore``.

Every trial is a :class:`~dsage_ray.ray.trainable.DSAGETrainable` whose Tune config is a flat
:meth:`RunConfig.to_flat` dict; grid axes are plain dotted keys (``variant``, ``seed``).
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any, Literal, Sequence

import ray
from ray import tune

from dsage_ray.config import RunConfig
from dsage_ray.domains import build_domain
from dsage_ray.ray.pool import DomainFactory, check_cluster_fits
from dsage_ray.ray.progress import ProgressLines, quiet_tune_output
from dsage_ray.ray.trainable import DSAGETrainable, resource_request

#: Which Tune entry point runs the trials.
TuneApi = Literal["tuner", "run"]


class ExperimentInterrupted(RuntimeError):
    """Tune returned before every trial spent its budget (Ctrl+C, a stopped driver)."""


def connect(address: str | None = None, *, num_cpus: int | None = None) -> None:
    """Joins the cluster at ``address`` (or ``RAY_ADDRESS``), else starts a local one.

    Args:
        address: ``"auto"``, ``"host:6379"`` or ``None``.
        num_cpus: Logical CPUs of a *local* cluster (ignored when joining one).
    """
    if ray.is_initialized():
        return
    address = address or os.environ.get("RAY_ADDRESS")
    if address:
        ray.init(address=address)
    else:
        ray.init(num_cpus=num_cpus, include_dashboard=False)


def grid_param_space(base: RunConfig, *, variants: Sequence[str], seeds: Sequence[int]) -> dict[str, Any]:
    """The flat base config with ``variant`` and ``seed`` turned into grid axes.

    Each grid point is re-validated by :meth:`RunConfig.build` inside its trial, where the variant
    layer (e.g. ``surrogate.kind``) is applied; so the explicit keys of the base must not pin what
    a variant sets. Only the keys that differ from the defaults of ``(domain, preset, variant)``
    are kept for that reason.
    """
    for variant in variants:  # fail before any trial starts, naming the bad variant
        RunConfig.build({"domain": base.domain, "preset": base.preset, "variant": variant})
    defaults = RunConfig.build({"domain": base.domain, "preset": base.preset, "variant": base.variant}).to_flat()
    explicit = {key: value for key, value in base.to_flat().items() if defaults.get(key) != value}
    explicit.update({
        "domain": base.domain,
        "preset": base.preset,
        "variant": tune.grid_search(list(variants)),
        "seed": tune.grid_search(list(seeds)),
    })
    return explicit


def check_resources(config: RunConfig) -> None:
    """Fails fast, naming the keys, when one trial's placement group can never be placed."""
    bundles = resource_request(config).bundles
    check_cluster_fits(
        bundles=bundles,
        what=(f"one trial (ray.trial_cpus={config.ray.trial_cpus:g} + ray.num_workers={config.ray.num_workers} × "
              f"ray.cpus_per_worker={config.ray.cpus_per_worker:g})"),
    )


def run_experiment(
    param_space: dict[str, Any],
    *,
    name: str,
    storage_path: str | Path,
    api: TuneApi = "tuner",
    resume: bool = False,
    max_failures: int = 2,
    checkpoint_every: int = 1,
    domain_factory: DomainFactory = build_domain,
    verbose: int = 0,
) -> Path:
    """Runs every trial of ``param_space`` to its evaluation budget; returns the experiment folder.

    Args:
        param_space: Flat Tune config (possibly with ``tune.grid_search`` axes).
        name: Experiment folder name under ``storage_path``.
        storage_path: Where results, checkpoints and TensorBoard files go (made absolute: Tune needs it).
        api: ``"tuner"`` (``tune.Tuner``) or ``"run"`` (``tune.run``).
        resume: Continue an interrupted experiment of the same name (unfinished and errored trials
            resume from their last checkpoints).
        max_failures: Times a crashed trial is restored from its last checkpoint.
        checkpoint_every: Outer iterations between checkpoints.
        domain_factory: Builds the domain in the trial and in each simulator actor.
        verbose: Tune's own console verbosity (1 adds its status tables). A progress line per
            trial result is printed at every verbosity (:class:`~dsage_ray.ray.progress.ProgressLines`).

    Raises:
        ray.tune.TuneError: A trial failed more than ``max_failures`` times.
    """
    storage_path = str(Path(storage_path).expanduser().resolve())
    experiment_path = Path(storage_path) / name
    trainable = tune.with_parameters(DSAGETrainable, domain_factory=domain_factory)
    # Tune checkpoints at the end too, so a finished trial's last state is always on disk.
    checkpoint_config = tune.CheckpointConfig(checkpoint_frequency=checkpoint_every, checkpoint_at_end=True,
                                              num_to_keep=2)

    if api == "run":
        with quiet_tune_output():
            analysis = tune.run(
                trainable,
                name=name,
                config=param_space,
                storage_path=storage_path,
                checkpoint_config=checkpoint_config,
                max_failures=max_failures,
                resume="AUTO+ERRORED" if resume else False,
                verbose=verbose,
                callbacks=[ProgressLines()],
            )
        _check_finished(name, [trial.last_result for trial in analysis.trials])
        return Path(analysis.experiment_path)

    if resume and tune.Tuner.can_restore(experiment_path):
        tuner = tune.Tuner.restore(str(experiment_path), trainable=trainable, resume_errored=True)
    else:
        tuner = tune.Tuner(
            trainable,
            param_space=param_space,
            run_config=tune.RunConfig(
                name=name,
                storage_path=storage_path,
                checkpoint_config=checkpoint_config,
                failure_config=tune.FailureConfig(max_failures=max_failures),
                verbose=verbose,
                callbacks=[ProgressLines()],
            ),
        )
    with quiet_tune_output():
        results = tuner.fit()
    errors = [result.error for result in results if result.error is not None]
    if errors:
        raise tune.TuneError(f"{len(errors)} trial(s) failed; first error: {errors[0]}")
    _check_finished(name, [result.metrics for result in results])
    return Path(results.experiment_path)


def _check_finished(name: str, last_results: list[dict[str, Any] | None]) -> None:
    unfinished = sum(not (result or {}).get("done") for result in last_results)
    if unfinished:
        raise ExperimentInterrupted(
            f"{unfinished} of {len(last_results)} trials of {name!r} did not finish; continue them with --resume")
