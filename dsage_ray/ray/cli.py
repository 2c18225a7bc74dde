"""Ray entry points for ``dsage-ray run`` (one Tune trial) and ``dsage-ray ablate`` (a grid).

:mod:`dsage_ray.cli` parses arguments and calls these; everything Ray-specific lives here.
"""

from __future__ import annotations

from pathlib import Path
from typing import Sequence

from dsage_ray.config import PAPER_COMPARISON, RunConfig
from dsage_ray.ray.experiment import TuneApi, check_resources, connect, grid_param_space, run_experiment


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
    connect(address)
    check_resources(config)
    experiment = run_experiment(config.to_flat(), name=config.name, storage_path=out_dir, api="tuner",
                                resume=resume, max_failures=max_failures, checkpoint_every=config.checkpoint_every)
    (trial_dir,) = {params.parent for params in experiment.glob("*/params.json")}
    return trial_dir


def ablate(
    config: RunConfig,
    *,
    seeds: int | Sequence[int] = 5,
    variants: Sequence[str] | None = None,
    workers: int | None = None,
    address: str | None = None,
    resume: bool = False,
    out_dir: str | Path = "tb_logs",
    api: TuneApi = "tuner",
    max_failures: int = 2,
) -> Path:
    """Runs the variant × seed grid of the paper as one Tune experiment; returns its folder.

    Args:
        config: The base config (domain, preset, explicit overrides); ``variant`` and ``seed``
            become grid axes.
        seeds: How many seeds (``0..K-1``) or the seeds themselves.
        variants: Variants to compare; defaults to the domain's paper comparison.
        workers, address, resume, out_dir, max_failures: As in :func:`run_with_tune`.
        api: ``"tuner"`` or ``"run"`` (``tune.run``).
    """
    if workers is not None:
        config = config.replace(ray__num_workers=workers)
    seed_list = list(range(seeds)) if isinstance(seeds, int) else list(seeds)
    if variants is None:
        variants = PAPER_COMPARISON[config.domain]
    connect(address)
    check_resources(config)
    param_space = grid_param_space(config, variants=variants, seeds=seed_list)
    return run_experiment(param_space, name=config.name, storage_path=out_dir, api=api, resume=resume,
                          max_failures=max_failures, checkpoint_every=config.checkpoint_every)
