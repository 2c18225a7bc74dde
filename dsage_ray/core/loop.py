"""The one run loop: a runner stepped to its budget, with callbacks, checkpoints and the run folder's outputs.

"Its budget" is :attr:`DSAGE.done <dsage_ray.core.runner.DSAGE.done>`: the evaluation budget, or the
time budget (``time_budget``, which cuts short the batch under evaluation when it runs out). Either way
the run ends at the end of an iteration, checkpointed and with its outputs written, so ``--resume``
(with a larger time budget) continues it.

A ``--local`` run (:func:`run_locally`, also the audit's in-process search) drives a :class:`RunLoop`
itself with :meth:`RunLoop.run`; a Tune trial (:class:`dsage_ray.ray.trainable.DSAGETrainable`)
calls :meth:`RunLoop.step`, :meth:`RunLoop.save` and :meth:`RunLoop.restore` when Tune asks. Both
therefore do the same per-iteration work in the same order and write the same checkpoint file
(:mod:`dsage_ray.core.checkpoint`), which is what makes their archives identical.

Nothing here imports Ray.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any, Mapping, Protocol, Sequence

from dsage_ray.core.checkpoint import CHECKPOINT_NAME, load_checkpoint, save_checkpoint
from dsage_ray.errors import InputError
from dsage_ray.io import folder_lock

if TYPE_CHECKING:
    from dsage_ray.config import RunConfig
    from dsage_ray.core.runner import DSAGE
    from dsage_ray.core.snapshot import RunSnapshot
    from dsage_ray.types import Domain, Evaluator


class LoopCallback(Protocol):
    """What a :class:`RunLoop` calls: after every outer iteration, and once when it closes.

    A callback may also define ``on_start(runner)``, called when :meth:`RunLoop.run` starts (after a
    resume, so it sees the restored runner).
    """

    def on_step(self, run: "RunSnapshot", metrics: Mapping[str, float]) -> None:
        """The run just finished an outer iteration with these metrics (``run`` is read-only)."""

    def close(self) -> None:
        """The loop is done with the callback (flush files, close progress bars)."""


class RunLoop:
    """A runner, its run folder and its callbacks: one outer iteration at a time.

    Args:
        runner: The run.
        out_dir: The run folder: ``metrics.json``, ``archive.csv``, ``heatmap.png`` and the elites are
            written there once the evaluation or time budget is spent.
        callbacks: Called after every iteration in this order (TensorBoard, progress lines, ...) and
            closed by :meth:`close`.
    """

    def __init__(self, *, runner: "DSAGE", out_dir: str | Path, callbacks: Sequence[LoopCallback] = ()) -> None:
        self.runner = runner
        self.out_dir = Path(out_dir)
        self.callbacks = list(callbacks)

    @property
    def done(self) -> bool:
        return self.runner.done

    def step(self) -> dict[str, float]:
        """One outer iteration, then the callbacks; the run folder's outputs once a budget is spent."""
        metrics = self.runner.step()
        snapshot = self.runner.snapshot()
        for callback in self.callbacks:
            callback.on_step(snapshot, metrics)
        if self.runner.done:
            self.runner.write_outputs(self.out_dir)
        return metrics

    def save(self, path: str | Path) -> Path:
        """Writes the runner's full state to the checkpoint file ``path``."""
        return save_checkpoint(self.runner.state_dict(), path)

    def restore(self, path: str | Path) -> None:
        """Continues from the checkpoint file ``path`` exactly where the saved run stood."""
        self.runner.load_state_dict(load_checkpoint(path))

    def run(self, *, checkpoint: str | Path) -> None:
        """Steps until the evaluation or time budget is spent, saving ``checkpoint`` after every outer iteration
        (so a finished run's checkpoint holds its final archive)."""
        snapshot = self.runner.snapshot()
        for callback in self.callbacks:
            on_start = getattr(callback, "on_start", None)
            if on_start is not None:
                on_start(snapshot)
        while not self.runner.done:
            self.step()
            self.save(checkpoint)

    def close(self) -> None:
        for callback in self.callbacks:
            callback.close()


def run_locally(
    config: "RunConfig",
    *,
    out_dir: str | Path,
    resume: bool = False,
    domain: "Domain | None" = None,
    evaluator: "Evaluator | None" = None,
    console: bool = True,
) -> Path:
    """Runs DSAGE in this process into ``out_dir``: checkpoints, TensorBoard events, outputs, progress.

    Args:
        config: The run's config (``image_every`` applies).
        out_dir: The run folder; its checkpoint is ``out_dir/``:data:`~dsage_ray.core.checkpoint.CHECKPOINT_NAME`.
        resume: Continue the run in ``out_dir`` from its checkpoint.
        domain: The domain (default: built from ``config``).
        evaluator: Evaluates solutions for real (default: in this process).
        console: Show progress bars and a progress line per outer iteration.

    Returns:
        ``out_dir``.

    Raises:
        InputError: ``out_dir`` already holds a run and ``resume`` is not set, or holds none and it is.
        CheckpointError: The checkpoint to resume from is damaged, foreign, or from another pyribs.
    """
    from dsage_ray.core.progress import ConsoleProgress
    from dsage_ray.core.runner import DSAGE
    from dsage_ray.core.snapshot import RunSnapshot
    from dsage_ray.core.tensorboard_log import RunTensorBoard

    out_dir = Path(out_dir)
    checkpoint = out_dir / CHECKPOINT_NAME
    if checkpoint.exists() and not resume:
        raise InputError(f"{out_dir} already holds a run: pass --resume to continue it, or another --out")
    if resume and not checkpoint.exists():
        raise InputError(f"{out_dir} holds no run to resume ({CHECKPOINT_NAME} is missing)")
    with folder_lock(out_dir, what="run"):  # before the runner: an unwritable folder fails before any work
        progress = ConsoleProgress(budget=config.budget, time_budget=config.time_budget) if console else None
        runner = DSAGE(config=config, domain=domain, evaluator=evaluator,
                       progress=progress.phase if progress is not None else None)
        callbacks: list[Any] = [RunTensorBoard(logdir=out_dir, image_every=config.image_every)]
        if progress is not None:
            callbacks.append(progress)
        loop = RunLoop(runner=runner, out_dir=out_dir, callbacks=callbacks)
        try:
            if resume:
                loop.restore(checkpoint)
                if console:
                    print(f"resumed at {runner.evals} evaluations, outer iteration {runner.outer_iteration}")
            loop.run(checkpoint=checkpoint)
            if console and runner.out_of_time and runner.evals < config.budget:
                print(f"time budget reached: {runner.wall_time:.0f} s of {config.time_budget:g} s after "
                      f"{runner.evals} of {config.budget} evaluations; a larger --time-budget with --resume "
                      f"continues")
        finally:
            loop.close()
    return out_dir
