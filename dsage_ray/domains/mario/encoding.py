"""One-hot Mario levels, padded to 64 × 64: the GAN's training input and the surrogate's input."""

from __future__ import annotations

import numpy as np

from dsage_ray.domains.mario.tiles import EMPTY, NUM_TILES

#: Side of the square the GAN works in; levels sit in its top-left corner.
PADDED_SIZE = 64


def one_hot_levels(levels: np.ndarray, *, size: int = PADDED_SIZE) -> np.ndarray:
    """One-hot encodes tile-index levels and pads them to ``size × size``.

    The padding is marked on channel 0 (empty), as in the original GAN's training data, so
    every pixel of the output is a valid one-hot vector.

    Args:
        levels: ``(n, rows, cols)`` or ``(rows, cols)`` integer array with ``rows, cols <= size``.
        size: Output height and width.

    Returns:
        ``(n, 17, size, size)`` float32 array.
    """
    levels = np.asarray(levels)
    if levels.ndim == 2:
        levels = levels[None]
    if levels.ndim != 3:
        raise ValueError(f"levels must have shape (n, rows, cols), got {levels.shape}")
    n, rows, cols = levels.shape
    if rows > size or cols > size:
        raise ValueError(f"levels of {rows}x{cols} do not fit in {size}x{size}")
    padded = np.full((n, size, size), EMPTY, dtype=np.int64)
    padded[:, :rows, :cols] = levels
    out = np.zeros((n, NUM_TILES, size, size), dtype=np.float32)
    # Scatter 1s at (sample, tile, row, col) without materialising an eye() lookup per pixel.
    np.put_along_axis(out, padded[:, None], 1.0, axis=1)
    return out
