"""The 17-tile Mario vocabulary and conversions between index arrays and level text.

A level is either an ``(16, width)`` integer array of tile indices or the Mario AI framework's
text form (one string per row). Everything that reaches the Java simulator goes through
:func:`validate_level` first, because the framework accepts malformed input silently (unknown
characters become air, a 1-column level "wins" with a NaN completion) or fails with an opaque
Java exception (empty or ragged levels). See the SPEC's Mario section.
"""

from __future__ import annotations

from pathlib import Path
from typing import Sequence

import numpy as np

from dsage_ray.errors import InputError

#: Tile index → framework character (the SPEC's Mario order; the GAN's channel order).
TILES: tuple[str, ...] = (
    "-",  # 0 empty
    "*",  # 1 cannon (bullet bill)
    "y",  # 2 spiky
    "g",  # 3 goomba
    "k",  # 4 green koopa
    "r",  # 5 red koopa
    "t",  # 6 pipe
    "S",  # 7 brick
    "!",  # 8 coin question block
    "@",  # 9 power-up question block
    "F",  # 10 flag (exit)
    "X",  # 11 ground
    "%",  # 12 jump-through platform
    "M",  # 13 Mario start
    "|",  # 14 platform background
    "o",  # 15 coin
    "#",  # 16 solid block
)
NUM_TILES = len(TILES)
EMPTY = 0
CHAR_TO_INDEX: dict[str, int] = {c: i for i, c in enumerate(TILES)}

#: Rows of every level the framework plays here (the GAN crops to 16 × 56).
LEVEL_HEIGHT = 16
LEVEL_WIDTH = 56
#: Rows 0–8 are the "sky" for the sky-tiles measure (SPEC: Mario).
SKY_ROWS = 9

_LOOKUP = np.array(TILES)


class LevelError(InputError):
    """A level the simulator must not see; the message says what is wrong and where."""


def validate_level(level: str | Sequence[str] | np.ndarray) -> list[str]:
    """Checks a level and returns it as a list of row strings.

    Args:
        level: Level text (rows separated by newlines), a sequence of row strings, or an
            integer index array of shape ``(16, width)``.

    Returns:
        The rows, each of the same length.

    Raises:
        LevelError: If the level is not 16 rows, not rectangular, narrower than 2 columns, or
            contains characters (or indices) outside the 17-tile vocabulary.
    """
    if isinstance(level, np.ndarray):
        if level.ndim != 2:
            raise LevelError(f"level array must be 2-D (rows, columns), got shape {level.shape}")
        if not np.issubdtype(level.dtype, np.integer):
            raise LevelError(f"level array must hold integer tile indices, got dtype {level.dtype}")
        bad = (level < 0) | (level >= NUM_TILES)
        if bad.any():
            r, c = np.argwhere(bad)[0]
            raise LevelError(f"tile index {int(level[r, c])} at row {r}, column {c} is outside 0..{NUM_TILES - 1}")
        rows = ["".join(row) for row in _LOOKUP[level]]
    elif isinstance(level, str):
        rows = level.splitlines()
        # One trailing blank line is how text files end; anything else blank is an error below.
        while rows and rows[-1] == "":
            rows.pop()
    else:
        rows = [str(row) for row in level]
    if not rows:
        raise LevelError("level is empty")
    if len(rows) != LEVEL_HEIGHT:
        raise LevelError(f"level must have {LEVEL_HEIGHT} rows, got {len(rows)}")
    width = len(rows[0])
    for i, row in enumerate(rows):
        if len(row) != width:
            raise LevelError(f"level is not rectangular: row 0 has {width} columns, row {i} has {len(row)}")
    if width < 2:
        raise LevelError(f"level must be at least 2 columns wide, got {width}")
    for i, row in enumerate(rows):
        for j, ch in enumerate(row):
            if ch not in CHAR_TO_INDEX:
                raise LevelError(f"unknown tile character {ch!r} at row {i}, column {j} "
                                 f"(known: {''.join(TILES)})")
    return rows


def to_string(level: np.ndarray | str | Sequence[str]) -> str:
    """Returns validated level text, rows joined by newlines (no trailing newline)."""
    return "\n".join(validate_level(level))


def to_array(level: str | Sequence[str] | np.ndarray) -> np.ndarray:
    """Returns a validated ``(16, width)`` int64 array of tile indices."""
    rows = validate_level(level)
    return np.array([[CHAR_TO_INDEX[c] for c in row] for row in rows], dtype=np.int64)


def indices_to_string(level: np.ndarray) -> str:
    """Index array → text without validation (for arrays this package produced itself)."""
    return "\n".join("".join(row) for row in _LOOKUP[np.asarray(level)])


def sky_tiles(level: np.ndarray) -> int:
    """Number of non-empty tiles in rows 0–8 of a ``(16, width)`` index array (SPEC: Mario)."""
    return int(np.count_nonzero(np.asarray(level)[:SKY_ROWS] != EMPTY))


def load_level(path: str | Path) -> np.ndarray:
    """Reads and validates a level text file.

    Raises:
        LevelError: If the file cannot be read or is not a valid level (the message names the file).
    """
    path = Path(path)
    try:
        text = path.read_text()
    except (OSError, UnicodeDecodeError) as exc:
        raise LevelError(f"cannot read level file {path}: {getattr(exc, 'strerror', None) or exc}") from None
    try:
        return to_array(text)
    except LevelError as exc:
        raise LevelError(f"{path}: {exc}") from None
