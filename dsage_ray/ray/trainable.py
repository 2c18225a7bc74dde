"""One DSAGE run as a Tune trial: one ``step()`` is one outer iteration.

The trial reserves a placement group with one bundle for itself (surrogate training and the inner
loop) and one per simulator actor; the :class:`~dsage_ray.ray.pool.SimulatorPool` it creates is
captured by that group, so several trials share a machine or a cluster without deadlocking.

Checkpoints hold the runner's full :meth:`~dsage_ray.core.runner.DSAGE.state_dict` (archives,
dataset, model, optimizer, emitters, RNGs), so a trial restored after a crash continues exactly
as an uninterrupted one would.
"""

from __future__ import annotations

import io
from pathlib import Path
from typing import Any

import numpy as np
import ray
import torch
from ray import tune

from dsage_ray.config import RunConfig
from dsage_ray.domains import build_domain
from dsage_ray.io import atomic_write_bytes
from dsage_ray.ray.pool import DomainFactory, SimulatorPool

#: File inside a Tune checkpoint directory that holds the runner's state.
STATE_FILE = "runner_state.pt"


def resource_request(config: RunConfig) -> tune.PlacementGroupFactory:
    """The trial's bundles: ``[{CPU: trial_cpus}] + [{CPU: cpus_per_worker}] * num_workers``."""
    bundles = [{"CPU": config.ray.trial_cpus}] + [{"CPU": config.ray.cpus_per_worker}] * config.ray.num_workers
    return tune.PlacementGroupFactory(bundles)


class DSAGETrainable(tune.Trainable):
    """A Tune Trainable wrapping :class:`dsage_ray.core.runner.DSAGE`.

    Its Tune config is a flat :meth:`RunConfig.to_flat` dict, so every config key can be a
    ``tune.grid_search`` axis. Extra constructor arguments go through ``tune.with_parameters``.

    Results: the runner's metrics, ``done`` once the evaluation budget is spent, and the pool's
    fault counters (``pool_actor_deaths``, ``pool_resubmitted_chunks``).
    """

    def setup(self, config: dict[str, Any], domain_factory: DomainFactory = build_domain) -> None:
        from dsage_ray.core.runner import DSAGE

        self.run_config = RunConfig.build(config)
        # One torch thread per reserved CPU unless told otherwise: several trials and simulators
        # share the cores, and oversubscribed intra-op threads slow surrogate training down
        # several times over.
        ray_config = self.run_config.ray
        torch.set_num_threads(ray_config.trial_threads or max(1, int(ray_config.trial_cpus)))
        domain = domain_factory(self.run_config)
        # num_workers = 0 keeps evaluation in the trial process (useful on a 1-CPU machine).
        self.pool = (SimulatorPool(config=self.run_config, domain_factory=domain_factory)
                     if self.run_config.ray.num_workers > 0 else None)
        self.runner = DSAGE(config=self.run_config, evaluator=self.pool, domain=domain)
        self._writer = None
        # Reported so that a misplaced pool (actors outside the trial's bundles) is visible.
        trial_group = ray.get_runtime_context().get_placement_group_id()
        self._pool_in_trial_group = float(self.pool is not None and trial_group is not None and all(
            info["placement_group_id"] == trial_group for info in self.pool.actor_info))

    @classmethod
    def default_resource_request(cls, config: dict[str, Any]) -> tune.PlacementGroupFactory:
        return resource_request(RunConfig.build(config))

    # ----------------------------------------------------------------------------------- steps

    def step(self) -> dict[str, Any]:
        metrics = self.runner.step()
        result: dict[str, Any] = dict(metrics)
        result["done"] = self.runner.done
        if self.pool is not None:
            result["pool_actor_deaths"] = self.pool.stats.actor_deaths
            result["pool_resubmitted_chunks"] = self.pool.stats.resubmitted_chunks
            result["pool_in_trial_placement_group"] = self._pool_in_trial_group
        iteration = int(metrics.get("outer_iteration", self.iteration + 1))
        if iteration % self.run_config.image_every == 0 or self.runner.done:
            self._log_images(iteration)
        if self.runner.done:
            self.runner.write_outputs(self.output_dir)
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

    def _log_images(self, iteration: int) -> None:
        """Archive heatmap, sample elite levels spread over the archive, and the surrogate's
        predicted-vs-true measures (paper Fig. 9)."""
        from tensorboardX import SummaryWriter

        from dsage_ray.core.outputs import heatmap_image, render_elites, scatter_png

        if self._writer is None:
            self.output_dir.mkdir(parents=True, exist_ok=True)
            self._writer = SummaryWriter(logdir=str(self.output_dir), filename_suffix=".images")
        measure_names = tuple(self.runner.domain.measure_names)
        archive = self.runner.ground_truth_archive
        if len(archive) > 0:
            heatmap = heatmap_image(archive, title=f"iteration {iteration}", measure_names=measure_names)
            self._writer.add_image("archive/heatmap", heatmap, iteration, dataformats="HWC")
            if getattr(self.runner.domain, "render", None) is not None:
                elites = render_elites(archive, self.runner.domain, self.run_config.image_levels)
                for rank, (_, png) in enumerate(elites):
                    self._writer.add_image(f"levels/elite_{rank}", _png_to_array(png), iteration, dataformats="HWC")
        predictions = getattr(self.runner, "last_predictions", None)
        if predictions is not None:
            predicted, true = (np.asarray(a) for a in predictions)
            if len(true):
                scatter = _png_to_array(scatter_png(predicted, true, measure_names))
                self._writer.add_image("surrogate/predicted_vs_true_measures", scatter, iteration,
                                       dataformats="HWC")
        self._writer.flush()

    # ------------------------------------------------------------------------------ checkpoints

    def save_checkpoint(self, checkpoint_dir: str) -> None:
        buffer = io.BytesIO()
        torch.save(self.runner.state_dict(), buffer)
        # Atomic: a crash mid-write never leaves a truncated state file to restore from.
        atomic_write_bytes(Path(checkpoint_dir) / STATE_FILE, buffer.getvalue())

    def load_checkpoint(self, checkpoint: str | dict | None) -> None:
        path = Path(checkpoint) / STATE_FILE
        # Our own file: it holds archives and RNG states, not only tensors.
        state = torch.load(path, map_location="cpu", weights_only=False)
        self.runner.load_state_dict(state)

    def cleanup(self) -> None:
        if self._writer is not None:
            self._writer.close()
        if self.pool is not None:
            self.pool.close()


def _png_to_array(png: bytes) -> np.ndarray:
    from PIL import Image

    return np.asarray(Image.open(io.BytesIO(png)).convert("RGB"))

