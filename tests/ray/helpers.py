"""Shared pieces of the Ray tests: a small config and domain factories the actors can import."""

from __future__ import annotations

import os
import time
from pathlib import Path

import numpy as np

from dsage_ray.config import RunConfig
from dsage_ray.ray.trainable import DSAGETrainable
from tests.fakes import SMALL_RUN, BitmapDomain

#: tests.fakes.SMALL_RUN sized for a Tune trial: a longer budget, and images every iteration.
SMALL = {
    **SMALL_RUN,
    "budget": 120,
    "surrogate.epochs": 2,
    "image_every": 1,
    "ray.num_workers": 1,
    "ray.cpus_per_worker": 0.5,
    "ray.trial_cpus": 0.5,
    # One solution per task: the fault tests kill actors mid-batch and need work still in flight.
    "experimental.chunk_size": 1,
}


def small_config(**overrides) -> RunConfig:
    return RunConfig.build({**SMALL, **{k.replace("__", "."): v for k, v in overrides.items()}})


class RenderableBitmapDomain(BitmapDomain):
    """``BitmapDomain`` whose elite images also work for int8 solutions (trials write elite PNGs)."""

    def render(self, solution, occupancy):
        return super().render(np.asarray(solution, dtype=np.float32), occupancy)


def bitmap_domain(config: RunConfig) -> BitmapDomain:
    return RenderableBitmapDomain()


#: The seed :class:`SlowBitmapDomain` raises on.
RAISING_SEED = 13


class SlowBitmapDomain(RenderableBitmapDomain):
    """Each evaluation sleeps ``base + extra·(walls in the first row)`` seconds: uneven episodes.

    Evaluating with seed :data:`RAISING_SEED` raises (a simulator bug, not a dead process); a
    DSAGE run never draws that seed.
    """

    def __init__(self, *, base_s: float = 0.01, extra_s: float = 0.005) -> None:
        super().__init__()
        self.base_s = base_s
        self.extra_s = extra_s

    def evaluate(self, solution, seed):
        walls = np.asarray(solution).reshape(8, 8)[0].sum()
        time.sleep(self.base_s + self.extra_s * float(walls))
        if seed == RAISING_SEED:
            raise RuntimeError("injected failure")
        return super().evaluate(solution, seed)


def slow_bitmap_domain(config: RunConfig) -> SlowBitmapDomain:
    return SlowBitmapDomain()


def archive_snapshot(archive) -> tuple:
    data = archive.data()
    order = np.argsort(data["index"])
    return (data["index"][order].tolist(), data["objective"][order].tolist(), data["solution"][order].tolist())


class CrashOnceTrainable(DSAGETrainable):
    """Kills its own process after ``crash_after`` steps, once (a marker file remembers)."""

    def setup(self, config, domain_factory=bitmap_domain, crash_marker: str = "", crash_after: int = 2):
        super().setup(config, domain_factory=domain_factory)
        self._crash_marker = Path(crash_marker)
        self._crash_after = crash_after

    def step(self):
        result = super().step()
        if self.iteration + 1 == self._crash_after and not self._crash_marker.exists():
            self._crash_marker.touch()
            os._exit(1)  # a hard crash: no cleanup, no exception for Tune to catch
        return result


def tensorboard_tags(trial_dir) -> tuple[set[str], set[str]]:
    """Scalar and image tags of every TensorBoard event file in a trial folder."""
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    scalars, images = set(), set()
    for event_file in trial_dir.glob("events.out.tfevents.*"):
        accumulator = EventAccumulator(str(event_file), size_guidance={"images": 0})
        accumulator.Reload()
        scalars |= set(accumulator.Tags()["scalars"])
        images |= set(accumulator.Tags()["images"])
    return scalars, images


def tensorboard_scalars(folder, prefix: str = "") -> dict[str, list[tuple[int, float]]]:
    """``{tag: [(step, value), ...]}`` of the scalars starting with ``prefix`` in a folder's event files."""
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    scalars: dict[str, list[tuple[int, float]]] = {}
    for event_file in sorted(Path(folder).glob("events.out.tfevents.*")):
        accumulator = EventAccumulator(str(event_file), size_guidance={"scalars": 0})
        accumulator.Reload()
        for tag in accumulator.Tags()["scalars"]:
            if tag.startswith(prefix):
                scalars.setdefault(tag, []).extend((e.step, e.value) for e in accumulator.Scalars(tag))
    return scalars
