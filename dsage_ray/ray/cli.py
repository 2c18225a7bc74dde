"""Ray entry points for ``dsage-ray run`` (one Tune trial) and ``dsage-ray ablate`` (a grid).

:mod:`dsage_ray.cli` parses arguments and calls these; everything Ray-specific lives here.
"""

from __future__ import annotations

from pathlib import Path
from typing import Sequence

from dsage_ray.config import RunConfig
from dsage_ray.ray.experiment import (TuneApi, ablation_axes, check_resources, connect, grid_configs,
                                      grid_param_space, run_experiment)


def run_with_tune(
    config: RunConfig,
    *,
    workers: int | None = None,
    address: str | None = None,
    resume: bool = False,
    out_dir: str | Path = "tb_logs",
    max_failures: int = 2,
) -> Path:
    """Runs one DSAGE run as a single Tune trial; returns its trial folder.

    The trial folder (``out_dir/<name>/<trial>``) holds the run outputs (``metrics.json``,
    ``archive.csv``, ``heatmap.png``, elites), Tune's results and checkpoints and the TensorBoard
    files. ``resume=True`` continues ``out_dir/<name>``, so pass the same ``out_dir`` again.

    Args:
        config: The run's config; its ``name`` names the experiment folder.
        workers: Simulator actors (overrides ``ray.num_workers``).
        address: A running cluster to join (``ray start --head`` prints it); ``None`` uses
            ``RAY_ADDRESS`` or starts a local cluster.
        resume: Continue ``out_dir/<name>`` from its last checkpoint.
        out_dir: Storage folder (TensorBoard: ``tensorboard --logdir out_dir``).
        max_failures: Restores of a crashed trial from its last checkpoint.
    """
    if workers is not None:
        config = config.replace(ray__num_workers=workers)
    check_resources(config, address=address)  # before a local cluster starts
    connect(address)
    check_resources(config)
    experiment = run_experiment(config.to_flat(), name=config.name, storage_path=out_dir, api="tuner",
                                resume=resume, max_failures=max_failures, checkpoint_every=config.checkpoint_every)
    (trial_dir,) = {params.parent for params in experiment.glob("*/params.json")}
    return trial_dir


def ablate(
    config: RunConfig,
    *,
    grid: Sequence[str] = (),
    seeds: int | Sequence[int] | None = None,
    variants: Sequence[str] | None = None,
    workers: int | None = None,
    address: str | None = None,
    resume: bool = False,
    out_dir: str | Path = "tb_logs",
    api: TuneApi = "tuner",
    max_failures: int = 2,
) -> Path:
    """Runs a grid of DSAGE runs as one Tune experiment; returns its folder.

    Every grid point is validated before Ray starts, so a bad key or value (an unknown variant
    included) costs no cluster start.

    Args:
        config: The base config (domain, preset, explicit overrides).
        grid: ``KEY=V1,V2`` axes over any config key (see :func:`~dsage_ray.ray.experiment.ablation_axes`).
        seeds: How many seeds (``0..K-1``) or the seeds themselves (default 5; or ``--grid seed=...``).
        variants: Variants to compare (or ``--grid variant=...``); defaults to the domain's paper
            comparison when nothing else is gridded, else the config's variant.
        workers, address, resume, out_dir, max_failures: As in :func:`run_with_tune`.
        api: ``"tuner"`` or ``"run"`` (``tune.run``).
    """
    if workers is not None:
        config = config.replace(ray__num_workers=workers)
    axes = ablation_axes(config, grid, variants=variants, seeds=seeds)
    param_space = grid_param_space(config, axes)
    configs = grid_configs(config, axes)[1]
    check_resources(*configs, address=address)  # before a local cluster starts
    connect(address)
    check_resources(*configs)
    return run_experiment(param_space, name=config.name, storage_path=out_dir, api=api, resume=resume,
                          max_failures=max_failures, checkpoint_every=config.checkpoint_every)
