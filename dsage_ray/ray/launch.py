"""Ray entry points of :func:`dsage_ray.run` (one Tune trial) and :func:`dsage_ray.ablate` (a grid).

Both check that a trial fits the machine before a local cluster starts, connect, and run the
experiment; what they return is what Tune reports (:class:`~dsage_ray.results.RunResult`).
"""

from __future__ import annotations

from pathlib import Path
from typing import Collection, Sequence

from dsage_ray.config import RunConfig
from dsage_ray.preflight import preflight
from dsage_ray.ray.experiment import (TuneApi, ablation_axes, check_resources, grid_configs,
                                      grid_param_space, run_experiment)
from dsage_ray.ray.session import start_ray
from dsage_ray.results import ExperimentResult, RunResult


def run_with_tune(
    config: RunConfig,
    *,
    address: str | None = None,
    resume: bool = False,
    out_dir: str | Path = "tb_logs",
    max_failures: int = 2,
) -> RunResult:
    """Runs one DSAGE run as a single Tune trial.

    The trial folder (``out_dir/<name>/<trial>``) holds the run outputs (``metrics.json``,
    ``archive.csv``, ``heatmap.png``, elites), Tune's results and checkpoints and the TensorBoard
    files. ``resume=True`` continues ``out_dir/<name>``, so pass the same ``out_dir`` again.

    Args:
        config: The run's config; its ``name`` names the experiment folder.
        address: A running cluster to join (``ray start --head`` prints it); ``None`` uses
            ``RAY_ADDRESS`` or starts a local cluster.
        resume: Continue ``out_dir/<name>`` from its last checkpoint.
        out_dir: Storage folder (TensorBoard: ``tensorboard --logdir out_dir``).
        max_failures: Restores of a crashed trial from its last checkpoint.

    Returns:
        The trial's folder and latest checkpoint, as Tune's result reports them.
    """
    check_resources(config, address=address)  # before a local cluster starts
    start_ray(address)
    check_resources(config)
    experiment = run_experiment(config.to_flat(), name=config.name, storage_path=out_dir, api="tuner",
                                resume=resume, max_failures=max_failures)
    (trial,) = experiment.trials
    return trial


def ablate(
    config: RunConfig,
    *,
    grid: Sequence[str] = (),
    seeds: int | Sequence[int] | None = None,
    variants: Sequence[str] | None = None,
    address: str | None = None,
    resume: bool = False,
    out_dir: str | Path = "tb_logs",
    api: TuneApi = "tuner",
    max_failures: int = 2,
    given: Collection[str] | None = None,
) -> ExperimentResult:
    """Runs a grid of DSAGE runs as one Tune experiment.

    Every grid point is validated, and its agents loaded (:func:`~dsage_ray.preflight.preflight`),
    before Ray starts, so a bad key, value or agent costs no cluster start.

    Args:
        config: The base config (domain, preset, explicit overrides).
        grid: ``KEY=V1,V2`` axes over any config key (see :func:`~dsage_ray.ray.experiment.ablation_axes`).
        seeds: How many seeds (``0..K-1``) or the seeds themselves (default 5; or ``--grid seed=...``).
        variants: Variants to compare (or ``--grid variant=...``); defaults to the domain's paper
            comparison when nothing else is gridded, else the config's variant.
        address, resume, out_dir, max_failures: As in :func:`run_with_tune`.
        api: ``"tuner"`` or ``"run"`` (``tune.run``).
        given: With ``resume``, the keys the user gave; only these must match the stored trials'
            (:func:`~dsage_ray.ray.experiment.refuse_changed_config`). None: every key.
    """
    axes = ablation_axes(config, grid, variants=variants, seeds=seeds)
    param_space = grid_param_space(config, axes)
    configs = grid_configs(config, axes)[1]
    preflight(*configs)
    check_resources(*configs, address=address)  # before a local cluster starts
    start_ray(address)
    check_resources(*configs)
    shape = " × ".join(f"{key} ({len(values)})" for key, values in axes.items())
    print(f"{config.name}: {shape} via {api}, storage {out_dir}", flush=True)
    return run_experiment(param_space, name=config.name, storage_path=out_dir, api=api, resume=resume,
                          max_failures=max_failures, given=given)
