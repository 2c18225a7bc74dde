"""Grid archives, their statistics and tabular export.

pyribs 0.12 objects (archives, emitters, schedulers) pickle completely, including every internal
``numpy.random.Generator`` (the archive's own RNG drives ``sample_elites``, which MAP-Elites parents
and CMA-ME restarts use); :mod:`dsage_ray.core.checkpoint` saves them that way, with the pyribs
version check that keeps a checkpoint from another release from restoring silently wrong.
"""

from __future__ import annotations

import math

from typing import Collection

import numpy as np
import pandas as pd
from numpy.typing import DTypeLike
from ribs.archives import ArchiveDataFrame, GridArchive

#: Name of the ancillary-data extra field (expected agent visits per level cell).
OCCUPANCY_FIELD = "occupancy"


def make_archive(
    *,
    solution_dim: int,
    dims: Collection[int],
    ranges: Collection[tuple[float, float]],
    occupancy_shape: tuple[int, ...] | None = None,
    seed: int | None = None,
    solution_dtype: DTypeLike = np.float64,
) -> GridArchive:
    """Builds a MAP-Elites grid archive (QD-score offset 0, as in the paper).

    Args:
        solution_dim: Length of one solution (256 for a 16×16 Maze bitmap, 32 for a Mario latent).
        dims: Cells per measure, e.g. ``(256, 162)``.
        ranges: ``(low, high)`` per measure.
        occupancy_shape: When given, every elite also stores a float32 ``occupancy`` field of this
            shape (the surrogate's predicted or the agent's real visit counts).
        seed: Seed of the archive's RNG, which ``sample_elites`` uses (and so do the emitters that
            pick parents from the archive).
        solution_dtype: dtype of stored solutions. Maze bitmaps fit in ``np.int8``: 256 bytes per
            elite instead of 2 KiB at float64, which matters for checkpoints of a 41,472-cell archive.

    Returns:
        An empty :class:`ribs.archives.GridArchive`.
    """
    extra_fields = None
    if occupancy_shape is not None:
        extra_fields = {OCCUPANCY_FIELD: (tuple(occupancy_shape), np.float32)}
    return GridArchive(
        solution_dim=solution_dim,
        dims=tuple(dims),
        ranges=tuple(tuple(r) for r in ranges),
        qd_score_offset=0.0,
        seed=seed,
        solution_dtype=solution_dtype,
        extra_fields=extra_fields,
    )


def archive_stats(archive: GridArchive) -> dict[str, float | int]:
    """Paper metrics of an archive.

    The QD-score is the plain sum of elite objectives (offset 0, SPEC: DSAGE), computed here rather than
    read from ``archive.stats`` so that it does not depend on the archive's ``qd_score_offset``.

    Returns:
        ``qd_score``, ``coverage`` (elites / cells), ``num_elites``, ``num_cells``,
        ``objective_mean`` and ``objective_max`` (NaN for an empty archive).
    """
    objective = np.asarray(archive.data("objective"), dtype=np.float64)
    empty = objective.size == 0
    return {
        "qd_score": float(objective.sum()),
        "coverage": objective.size / archive.cells,
        "num_elites": int(objective.size),
        "num_cells": int(archive.cells),
        "objective_mean": float("nan") if empty else float(objective.mean()),
        "objective_max": float("nan") if empty else float(objective.max()),
    }


def archive_to_dataframe(archive: GridArchive, *, flatten: bool = False) -> ArchiveDataFrame:
    """Exports the elites as pyribs' :class:`~ribs.archives.ArchiveDataFrame`.

    pyribs refuses to export fields with more than one dimension (such as a 16×16 occupancy). They
    are left out by default; with ``flatten=True`` they are flattened row-major into columns
    ``name_0 … name_{k-1}``, the naming pyribs uses for 1-D fields, so ``get_field(name)`` returns the
    flattened array.

    Args:
        archive: The archive to export.
        flatten: Flatten >1-D fields instead of leaving them out.

    Returns:
        One row per elite with columns ``solution_*``, ``objective``, ``measures_*``, ``threshold``,
        any exportable extra fields, then ``index``, in pyribs' order.
    """
    multi_dim = [name for name in archive.field_list if np.ndim(archive.data(name)) > 2]
    exportable = [name for name in archive.field_list if name not in multi_dim]
    df = archive.data(exportable, return_type="pandas")
    if not flatten or not multi_dim:
        return df
    columns = {}
    for name in multi_dim:
        values = archive.data(name)
        values = values.reshape(len(values), -1)
        columns.update({f"{name}_{i}": values[:, i] for i in range(values.shape[1])})
    # Keep "index" last, as pyribs does.
    index = df.pop("index")
    return ArchiveDataFrame(pd.concat([df, pd.DataFrame(columns, index=df.index), index], axis=1))


#: Margin of a zoomed heatmap around the occupied cells: this fraction of their span, at least
#: :data:`HEATMAP_MIN_MARGIN` cells.
HEATMAP_MARGIN = 0.1
HEATMAP_MIN_MARGIN = 2


def zoom_window(low: int, high: int, cells: int) -> tuple[int, int]:
    """The cells ``low..high`` (inclusive) that elites occupy along one measure, padded by
    :data:`HEATMAP_MARGIN` of their span (at least :data:`HEATMAP_MIN_MARGIN` cells) and clipped to the grid."""
    pad = max(HEATMAP_MIN_MARGIN, math.ceil(HEATMAP_MARGIN * (high - low + 1)))
    return max(0, low - pad), min(cells - 1, high + pad)
