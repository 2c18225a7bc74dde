"""One DSAGE run as a Tune trial: one ``step()`` is one outer iteration.

The trial reserves a placement group with one bundle for itself (surrogate training and the inner
loop) and one per simulator actor; the :class:`~dsage_ray.ray.pool.SimulatorPool` it creates is
captured by that group, so several trials share a machine or a cluster without deadlocking.

The trial is a :class:`~dsage_ray.core.loop.RunLoop` driven by Tune: the same per-iteration work
as ``--local``, and the same checkpoint file (:mod:`dsage_ray.core.checkpoint`) inside each of
Tune's checkpoint folders. It holds the runner's full
:meth:`~dsage_ray.core.runner.DSAGE.state_dict` (archives, dataset, model, optimizer, emitters,
RNGs), so a trial restored after a crash continues exactly as an uninterrupted one would. Torch
threads are the runner's business (``torch_threads``, pinned during each step as in ``--local``),
so a trial computes what an in-process run computes.
"""

from __future__ import annotations

import logging
from pathlib import Path
from typing import Any, Sequence

import ray
from ray import tune

from dsage_ray.agents.shipping import AgentFiles, install_agent_files
from dsage_ray.config import RunConfig
from dsage_ray.core.checkpoint import CHECKPOINT_NAME
from dsage_ray.core.loop import RunLoop
from dsage_ray.core.tensorboard_log import RunTensorBoard
from dsage_ray.domains import build_domain
from dsage_ray.ray.pool import DomainFactory, SimulatorPool


def resource_request(config: RunConfig) -> tune.PlacementGroupFactory:
    """The trial's bundles: ``[{CPU: trial_cpus}] + [{CPU: cpus_per_worker}] * num_workers``."""
    bundles = [{"CPU": config.ray.trial_cpus}] + [{"CPU": config.ray.cpus_per_worker}] * config.ray.num_workers
    return tune.PlacementGroupFactory(bundles)


class DSAGETrainable(tune.Trainable):
    """A Tune Trainable wrapping :class:`dsage_ray.core.runner.DSAGE`.

    Its Tune config is a flat :meth:`RunConfig.to_flat` dict, so every config key can be a
    ``tune.grid_search`` axis. Extra constructor arguments go through ``tune.with_parameters``.

    Results: the runner's metrics (``wall_time`` and ``cpu_time`` among them: the trial process's, not
    the simulator actors' CPU), ``done`` once the evaluation or the time budget is spent
    (:attr:`DSAGE.done <dsage_ray.core.runner.DSAGE.done>`), ``budget``, and
    the pool's fault counters (``pool_actor_deaths``, ``pool_resubmitted_chunks``). The trial also
    writes its own TensorBoard events (``dsage/*`` scalars against evaluations, and images) into
    its folder; see :class:`~dsage_ray.core.tensorboard_log.RunTensorBoard`.
    """

    def setup(self, config: dict[str, Any], domain_factory: DomainFactory = build_domain,
              agent_files: Sequence[AgentFiles] | None = None) -> None:
        from dsage_ray.core.runner import DSAGE

        # The agents' files, from the driver through Ray's object store: this trial may run on a node without them.
        install_agent_files(agent_files or ())
        self.run_config = RunConfig.build(config)
        # Tune logs every checkpoint at INFO from this process ("Checkpoint successfully created at");
        # one per outer iteration buries the driver's progress lines. Warnings still show.
        logging.getLogger("ray.train._internal.storage").setLevel(logging.WARNING)
        domain = domain_factory(self.run_config)
        # num_workers = 0 keeps evaluation in the trial process (useful on a 1-CPU machine).
        self.pool = (SimulatorPool(config=self.run_config, domain_factory=domain_factory, agent_files=agent_files)
                     if self.run_config.ray.num_workers > 0 else None)
        self.runner = DSAGE(config=self.run_config, evaluator=self.pool, domain=domain)
        tensorboard = RunTensorBoard(logdir=self.output_dir, image_every=self.run_config.image_every)
        self.loop = RunLoop(runner=self.runner, out_dir=self.output_dir, callbacks=[tensorboard])
        # Reported so that a misplaced pool (actors outside the trial's bundles) is visible.
        trial_group = ray.get_runtime_context().get_placement_group_id()
        self._pool_in_trial_group = float(self.pool is not None and trial_group is not None and all(
            info["placement_group_id"] == trial_group for info in self.pool.actor_info))

    @classmethod
    def default_resource_request(cls, config: dict[str, Any]) -> tune.PlacementGroupFactory:
        return resource_request(RunConfig.build(config))

    # ----------------------------------------------------------------------------------- steps

    def step(self) -> dict[str, Any]:
        metrics = self.loop.step()
        result: dict[str, Any] = dict(metrics)
        result["done"] = self.runner.done
        # The driver's progress line needs it, and an ablation's flat config may leave it at its default.
        result["budget"] = self.run_config.budget
        result["time_budget"] = self.run_config.time_budget
        if self.pool is not None:
            result["pool_actor_deaths"] = self.pool.stats.actor_deaths
            result["pool_resubmitted_chunks"] = self.pool.stats.resubmitted_chunks
            result["pool_in_trial_placement_group"] = self._pool_in_trial_group
        return result

    @property
    def output_dir(self) -> Path:
        """The trial directory in the experiment's storage when it is local, else the working dir.

        Tune's own TensorBoard scalars land in the storage trial directory; writing our images and
        the run's outputs there too keeps ``tensorboard --logdir <storage>`` complete without
        waiting for artifact syncing. Remote storage (S3, GCS) falls back to the working
        directory, which Tune uploads when ``SyncConfig(sync_artifacts=True)``.
        """
        storage = getattr(self, "_storage", None)
        if storage is not None:
            import pyarrow.fs

            if isinstance(storage.storage_filesystem, pyarrow.fs.LocalFileSystem):
                return Path(storage.trial_fs_path)
        return Path(self.logdir)

    # ------------------------------------------------------------------------------ checkpoints

    def save_checkpoint(self, checkpoint_dir: str) -> None:
        self.loop.save(Path(checkpoint_dir) / CHECKPOINT_NAME)

    def load_checkpoint(self, checkpoint: str | dict | None) -> None:
        self.loop.restore(Path(checkpoint) / CHECKPOINT_NAME)

    def cleanup(self) -> None:
        self.loop.close()
        if self.pool is not None:
            self.pool.close()

