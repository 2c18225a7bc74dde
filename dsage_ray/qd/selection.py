"""Which surrogate elites get a real evaluation: downsample, random or full (SPEC: DSAGE)."""

from __future__ import annotations

from typing import Callable, Sequence

import numpy as np
from ribs.archives import GridArchive

from dsage_ray.config import ConfigError, SelectionMethod
from dsage_ray.errors import did_you_mean

def select_solutions(
    archive: GridArchive,
    *,
    method: str,
    block: Sequence[int],
    count: int,
    rng: np.random.Generator,
    among: np.ndarray | None = None,
    priority: np.ndarray | None = None,
) -> np.ndarray:
    """Picks elites of ``archive`` for real evaluation.

    - ``downsample``: the cell grid is cut into blocks of ``block`` cells per measure (edge blocks may
      be smaller when a block size does not divide the grid), and one occupied elite is chosen
      uniformly at random per occupied block (with ``priority``: the block's highest, ties uniformly).
    - ``random``: ``count`` elites uniformly without replacement (all of them if fewer).
    - ``full``: every elite.

    The result depends only on the archive's contents and ``rng``, not on the order in which elites
    were inserted.

    Args:
        archive: The (surrogate) archive.
        method: ``downsample``, ``random`` or ``full``.
        block: Cells per block along each measure (``downsample`` only).
        count: Elites to pick (``random`` only).
        rng: Source of randomness; ``full`` does not draw from it.
        among: Archive indices to pick from (None: every elite); the method then sees only these elites.
        priority: One value per index of ``among`` (``downsample`` only): each block's pick is its highest.

    Returns:
        Sorted integer archive indices of the chosen elites; read their data with :func:`gather_elites`.

    Raises:
        ValueError: ``block`` is not one positive entry per measure.
        ConfigError: Unknown method.
    """
    if method not in SELECTION_METHODS:
        raise ConfigError(f"selection.method: unknown method {method!r} (known: {', '.join(SELECTION_METHODS)})"
                          f"{did_you_mean(method, SELECTION_METHODS)}")
    indices = np.sort(np.asarray(archive.data("index"), dtype=np.int64))
    if among is not None:
        among = np.asarray(among, dtype=np.int64)
        if priority is not None and len(priority) != len(among):
            raise ValueError(f"priority needs one value per index of among ({len(priority)} != {len(among)})")
        indices, _, positions = np.intersect1d(indices, among, return_indices=True)
        priority = None if priority is None else np.asarray(priority, dtype=np.float64)[positions]
    elif priority is not None:
        raise ValueError("priority needs among: the indices it ranks")
    if priority is None:
        priority = np.zeros(len(indices))
    return np.sort(indices[SELECTION_METHODS[method](archive, indices, block, count, rng, priority)])


def _downsample(archive: GridArchive, indices: np.ndarray, block: Sequence[int], count: int,
                rng: np.random.Generator, priority: np.ndarray) -> np.ndarray:
    return _one_per_block(archive, indices, block, rng, priority)


def check_same_cells(archive: GridArchive, other: GridArchive, name: str) -> None:
    if (tuple(archive.dims) != tuple(other.dims)
            or not all(np.allclose(a, b) for a, b in zip(archive.boundaries, other.boundaries))):
        raise ValueError(f"{name} needs a surrogate and a ground-truth archive with the same cells")


def _full(archive: GridArchive, indices: np.ndarray, block: Sequence[int], count: int,
          rng: np.random.Generator, priority: np.ndarray) -> np.ndarray:
    return np.arange(len(indices))


def _random(archive: GridArchive, indices: np.ndarray, block: Sequence[int], count: int,
            rng: np.random.Generator, priority: np.ndarray) -> np.ndarray:
    if count < 0:
        raise ValueError(f"count must be >= 0 (got {count})")
    return rng.choice(len(indices), size=min(count, len(indices)), replace=False)


#: Each ``selection.method``: ``pick(archive, sorted indices, block, count, rng, priority)`` → positions in the
#: indices. Its keys are the config's :data:`~dsage_ray.config.SelectionMethod`.
SELECTION_METHODS: dict[SelectionMethod, Callable[..., np.ndarray]] = {
    "downsample": _downsample,
    "random": _random,
    "full": _full,
}


def block_ids(archive: GridArchive, indices: np.ndarray, block: Sequence[int]) -> np.ndarray:
    """Flat id of the downsampling block that holds each archive index.

    Raises:
        ValueError: ``block`` is not one positive entry per measure.
    """
    block = np.asarray(block, dtype=np.int64)
    if block.shape != (archive.measure_dim,) or np.any(block < 1):
        raise ValueError(f"block must be {archive.measure_dim} positive cell counts (got {block.tolist()})")
    grid_shape = -(-np.asarray(archive.dims, dtype=np.int64) // block)  # ceil division
    block_coords = archive.int_to_grid_index(indices).astype(np.int64) // block
    return np.ravel_multi_index(tuple(block_coords.T), tuple(grid_shape))


def _one_per_block(archive: GridArchive, indices: np.ndarray, block: Sequence[int],
                   rng: np.random.Generator, priority: np.ndarray) -> np.ndarray:
    """Positions into ``indices`` (sorted) of one elite per occupied block: its highest ``priority``, ties chosen
    uniformly."""
    blocks = block_ids(archive, indices, block)
    if len(indices) == 0:
        return np.empty(0, dtype=np.int64)
    # Each elite gets an i.i.d. uniform key; the smallest key in a block is a uniform pick within it.
    keys = rng.random(len(indices))
    order = np.lexsort((keys, -priority, blocks))
    first_of_block = np.r_[True, blocks[order][1:] != blocks[order][:-1]]
    return np.sort(order[first_of_block])


def additions(archive: GridArchive, objective: np.ndarray,
              measures: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Whether each ``(objective, measures)`` would add to ``archive`` (its cell is empty, or holds a lower
    objective), and what it would add to the QD-score: its objective less the cell's elite's (less
    ``qd_score_offset`` in an empty cell)."""
    objective = np.asarray(objective, dtype=np.float64)
    occupied, elites = archive.retrieve(np.asarray(measures, dtype=np.float64))
    gain = objective - np.where(occupied, elites["objective"], archive.qd_score_offset)
    return ~occupied | (gain > 0), gain


def adds_to(archive: GridArchive, objective: np.ndarray, measures: np.ndarray) -> np.ndarray:
    """Whether each ``(objective, measures)`` would add to ``archive``: its cell is empty, or holds a lower objective."""
    return additions(archive, objective, measures)[0]


def gather_elites(archive: GridArchive, indices: np.ndarray) -> dict[str, np.ndarray]:
    """Every field (solution, objective, measures, extras, index) of the elites at ``indices``, in that order.

    Raises:
        KeyError: An index is not occupied.
    """
    data = archive.data()
    occupied = np.asarray(data["index"], dtype=np.int64)
    order = np.argsort(occupied)
    indices = np.asarray(indices, dtype=np.int64)
    pos = np.searchsorted(occupied[order], indices)
    found = pos < len(occupied)
    found[found] = occupied[order][pos[found]] == indices[found]
    if not np.all(found):
        raise KeyError(f"archive cells not occupied: {indices[~found][:10].tolist()}")
    rows = order[pos]
    return {name: values[rows] for name, values in data.items()}
