"""Our TensorBoard events for one run, and the command that opens them.

What is logged when, always with the number of real evaluations as the step, so runs with different
batch sizes (DSAGE, MAP-Elites, a resumed run) line up on the same axis:

* after every outer iteration, every metric of the iteration as a scalar ``dsage/<metric>``
  (``qd_score``, ``coverage``, ``objective_max``, the surrogate's errors, the phases' times, ...);
* within an iteration, ``dsage/qd_score``, ``dsage/coverage`` and ``dsage/objective_max`` also every
  ``ceil(budget / GROWTH_POINTS)`` evaluations (every evaluation up to a 500-evaluation budget): the
  ground-truth archive's values had the batch's results entered it one at a time, in evaluation order
  (:func:`dsage_ray.qd.growth.growth_curve`). An outer iteration evaluates its whole batch before the
  archive takes it, so without these a 300-evaluation demo's curves would have 2 or 3 points; with
  them they have about 300, and the last point of each iteration is the archive's own value. They are written when the
  iteration ends, not as the levels are evaluated;
* every ``image_every`` outer iterations, and once the budget is spent, images: ``archive/heatmap``,
  ``levels/elite_K`` and ``surrogate/predicted_vs_true_measures``.

Under Tune these events are the trial folder's only TensorBoard files (Tune's own logger is off).

One scalar has another axis: ``dsage/qd_score_vs_wall_time`` is the QD-score with the run's wall time
in whole seconds as the step (``wall_time``, cumulative across resumes), to compare searches at equal
time. It is a step, not the events' own wall-clock time, because TensorBoard's default x-axis is the
step and the events' times would count the pauses between a run and its resume; iterations ending in
the same second share a step.
"""

from __future__ import annotations

import io
import numbers
import os
import shlex
import shutil
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Mapping

import numpy as np

if TYPE_CHECKING:
    from dsage_ray.core.snapshot import RunSnapshot

#: Group of our scalars in TensorBoard (``dsage/qd_score``, ``dsage/coverage``, ...).
SCALAR_GROUP = "dsage"
#: The QD-score against whole seconds of wall time (the other scalars are against evaluations).
QD_SCORE_VS_WALL_TIME = f"{SCALAR_GROUP}/qd_score_vs_wall_time"


#: Elite levels drawn per image step, spread along the first measure.
ELITE_LEVELS = 4
#: The scalars the within-iteration curves add points to (``dsage/<name>``).
GROWTH_SCALARS = ("qd_score", "coverage", "objective_max")


class RunTensorBoard:
    """Writes one run's scalars every outer iteration (with the points of its
    :func:`~dsage_ray.qd.growth.growth_curve` before them)
    and its images every ``image_every``.

    The event file is created on the first :meth:`log`, so a run that never steps leaves none.

    Args:
        logdir: Folder of the event file (the run or trial folder).
        image_every: Outer iterations between images (images are also written once the budget is spent); 0: none.
    """

    def __init__(self, *, logdir: str | Path, image_every: int) -> None:
        self.logdir = Path(logdir)
        self.image_every = image_every
        self._writer = None

    def log(self, run: "RunSnapshot", metrics: Mapping[str, float]) -> None:
        """Logs the metrics of the iteration ``run`` just finished (and its images when due)."""
        if self._writer is None:
            from tensorboardX import SummaryWriter

            self.logdir.mkdir(parents=True, exist_ok=True)
            self._writer = SummaryWriter(logdir=str(self.logdir), filename_suffix=".dsage")
        step = int(metrics["evals"])
        self._log_growth(run, until=step)
        for key, value in metrics.items():
            if isinstance(value, numbers.Real) and not isinstance(value, bool):
                self._writer.add_scalar(f"{SCALAR_GROUP}/{key}", float(value), step)
        if "wall_time" in metrics:
            self._writer.add_scalar(QD_SCORE_VS_WALL_TIME, float(metrics["qd_score"]), int(metrics["wall_time"]))
        iteration = int(metrics["outer_iteration"])
        if self.image_every and (iteration % self.image_every == 0 or run.done):
            self._log_images(run, iteration=iteration, step=step)
        self._writer.flush()

    def _log_growth(self, run: "RunSnapshot", *, until: int) -> None:
        """The iteration's within-batch points, but the last: at ``until`` the iteration's own metrics are logged."""
        for point in run.growth:
            if point.evals < until:
                for name in GROWTH_SCALARS:
                    self._writer.add_scalar(f"{SCALAR_GROUP}/{name}", getattr(point, name), point.evals)

    def on_step(self, run: "RunSnapshot", metrics: Mapping[str, float]) -> None:
        """:class:`~dsage_ray.core.loop.RunLoop` callback: :meth:`log`."""
        self.log(run, metrics)

    def close(self) -> None:
        if self._writer is not None:
            self._writer.close()
            self._writer = None

    def _log_images(self, run: "RunSnapshot", *, iteration: int, step: int) -> None:
        """Archive heatmap, sample elite levels spread over the archive, and the surrogate's
        predicted-vs-true measures (paper Fig. 9)."""
        from dsage_ray.core.outputs import heatmap_image, render_elites, scatter_png

        measure_names = tuple(run.domain.measure_names)
        archive = run.archive
        if len(archive) > 0:
            # Zoomed to the occupied cells: over the measures' full ranges the elites are a few specks.
            heatmap = heatmap_image(archive, title=f"{step} evaluations (iteration {iteration})",
                                    measure_names=measure_names, zoom=True)
            self._writer.add_image("archive/heatmap", heatmap, step, dataformats="HWC")
            if getattr(run.domain, "render", None) is not None:
                for rank, (_, png) in enumerate(render_elites(archive, run.domain, ELITE_LEVELS)):
                    self._writer.add_image(f"levels/elite_{rank}", png_to_array(png), step, dataformats="HWC")
        predictions = run.last_predictions
        if predictions is not None:
            predicted, true = (np.asarray(a) for a in predictions)
            if len(true):
                scatter = png_to_array(scatter_png(predicted, true, measure_names))
                self._writer.add_image("surrogate/predicted_vs_true_measures", scatter, step, dataformats="HWC")


def png_to_array(png: bytes) -> np.ndarray:
    """A PNG as an ``(H, W, 3)`` uint8 array."""
    from PIL import Image

    return np.asarray(Image.open(io.BytesIO(png)).convert("RGB"))


def tensorboard_hint(folder: str | Path) -> str:
    """The exact shell command that opens ``folder`` in TensorBoard, e.g.
    ``.venv/bin/tensorboard --logdir tb_logs/maze_dsage/DSAGETrainable_1a2b3_00000_0_...``.

    The folder is relative to the working directory when it lies below it (absolute otherwise), and
    quoted for the shell. The executable is plain ``tensorboard`` when it is on the ``PATH``, else
    the one installed next to this Python (``make`` installs into ``.venv`` without activating it).
    """
    executable = "tensorboard"
    if shutil.which(executable) is None:
        beside_python = Path(sys.executable).parent / executable
        if beside_python.exists():
            executable = _relative_to_cwd(beside_python)
    return f"{shlex.quote(executable)} --logdir {shlex.quote(_relative_to_cwd(Path(folder)))}"


def _relative_to_cwd(path: Path) -> str:
    # os.path.abspath, not resolve(): a venv's bin/python is a symlink that must stay unresolved.
    absolute = Path(os.path.abspath(path))
    try:
        return str(absolute.relative_to(Path.cwd()))
    except ValueError:
        return str(absolute)
