"""What a finished run returns: its folder, its last checkpoint, its metrics and its archive.

A :class:`RunResult` is built from what the run itself reports (:func:`dsage_ray.run`: the folder of
an in-process run, or the path and latest checkpoint of the Tune ``Result``), never by searching
folders. Its metrics and archive are read from those files on first use.
"""

from __future__ import annotations

import dataclasses
import functools
import json
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from ribs.archives import GridArchive

    from dsage_ray.config import RunConfig


@dataclasses.dataclass(frozen=True, kw_only=True)
class RunResult:
    """One finished DSAGE run (or baseline).

    Attributes:
        config: The run's resolved config.
        path: The run folder: ``metrics.json``, ``archive.csv``, ``heatmap.png``, the elites and the
            TensorBoard events (a Tune trial folder, or the ``--out`` of an in-process run).
        checkpoint: The checkpoint file holding the run's final state
            (:mod:`dsage_ray.core.checkpoint`); ``dsage-ray run --resume`` continues from it.
    """

    config: "RunConfig"
    path: Path
    checkpoint: Path

    @functools.cached_property
    def metrics(self) -> list[dict[str, Any]]:
        """One dict per outer iteration (``evals``, ``qd_score``, ``coverage``, ...; ``metrics.json``)."""
        return json.loads((self.path / "metrics.json").read_text())

    @functools.cached_property
    def archive(self) -> "GridArchive":
        """The final ground-truth archive (a pyribs ``GridArchive``), read from :attr:`checkpoint`.

        Raises:
            CheckpointError: The checkpoint is missing, damaged or from an incompatible pyribs.
        """
        from dsage_ray.core.checkpoint import load_checkpoint

        return load_checkpoint(self.checkpoint)["archive"]


@dataclasses.dataclass(frozen=True, kw_only=True)
class ExperimentResult:
    """A Tune experiment of several runs (``dsage-ray ablate``).

    Attributes:
        path: The experiment folder (``experiments/summarize.py PATH`` reads it).
        trials: One result per trial, in Tune's trial order.
    """

    path: Path
    trials: tuple[RunResult, ...]
