"""Human-authored Mario levels from the ``mario-gpt`` wheel's data, mapped to the 17 tiles.

``mario_gpt/level.py`` holds ``FULL_LEVEL_STR_WITH_PATHS``: 14 rows of concatenated VGLC Super
Mario Bros levels. Importing ``mario_gpt`` would pull ``transformers``, so the file is located
through the installed distribution and its string literal is read with :mod:`ast`.
"""

from __future__ import annotations

import ast
import functools
import importlib.metadata
from pathlib import Path

import numpy as np

from dsage_ray.domains.mario.tiles import CHAR_TO_INDEX, LEVEL_HEIGHT, LEVEL_WIDTH
from dsage_ray.errors import ResourceError

#: VGLC character → our tile character (SPEC: Mario). ``x`` is a path overlay, not a tile.
VGLC_TO_TILE: dict[str, str] = {
    "-": "-", "x": "-", "X": "X", "S": "S", "o": "o",
    "?": "@", "Q": "!", "E": "g",
    "<": "t", ">": "t", "[": "t", "]": "t",
    "B": "*", "b": "*",
}
#: Sky rows added on top: the data has 14 rows, the framework plays 16.
EXTRA_SKY_ROWS = LEVEL_HEIGHT - 14


class MarioDataError(ResourceError):
    """The ``mario-gpt`` package (jar or level data) is missing or not what we expect."""


def mario_gpt_file(relative: str) -> Path:
    """Path of a file inside the installed ``mario-gpt`` distribution, without importing it.

    Raises:
        MarioDataError: If the distribution or the file is missing.
    """
    try:
        dist = importlib.metadata.distribution("mario-gpt")
    except importlib.metadata.PackageNotFoundError:
        raise MarioDataError("the 'mario-gpt' package is not installed "
                             "(pip install --no-deps mario-gpt==0.1.3)") from None
    path = Path(str(dist.locate_file(relative)))
    if not path.is_file():
        raise MarioDataError(f"mario-gpt is installed but {relative} is missing (looked at {path})")
    return path


@functools.lru_cache(maxsize=1)
def human_level_text() -> tuple[str, ...]:
    """The raw 14 VGLC rows of ``FULL_LEVEL_STR_WITH_PATHS``."""
    path = mario_gpt_file("mario_gpt/level.py")
    tree = ast.parse(path.read_text())
    for node in tree.body:
        if (isinstance(node, ast.Assign) and any(getattr(t, "id", None) == "FULL_LEVEL_STR_WITH_PATHS"
                                                 for t in node.targets)):
            rows = tuple(ast.literal_eval(node.value).strip("\n").split("\n"))
            break
    else:
        raise MarioDataError(f"{path} has no FULL_LEVEL_STR_WITH_PATHS")
    if len(rows) != 14 or len({len(r) for r in rows}) != 1:
        raise MarioDataError(f"{path}: expected 14 equal rows, got {len(rows)} rows "
                             f"of lengths {sorted({len(r) for r in rows})}")
    return rows


@functools.lru_cache(maxsize=1)
def human_level_array() -> np.ndarray:
    """All human levels as one ``(16, 7294)`` tile-index array (2 empty sky rows added)."""
    rows = human_level_text()
    unknown = set("".join(rows)) - set(VGLC_TO_TILE)
    if unknown:
        raise MarioDataError(f"human level data has unmapped characters {sorted(unknown)}")
    table = {ord(k): v for k, v in VGLC_TO_TILE.items()}
    mapped = [row.translate(table) for row in rows]
    body = np.array([[CHAR_TO_INDEX[c] for c in row] for row in mapped], dtype=np.int64)
    sky = np.zeros((EXTRA_SKY_ROWS, body.shape[1]), dtype=np.int64)
    array = np.concatenate([sky, body])
    array.flags.writeable = False
    return array


def human_windows(width: int = LEVEL_WIDTH, stride: int = 1) -> np.ndarray:
    """Every ``width``-wide window of the human levels, shape ``(n, 16, width)``.

    The source string concatenates levels, so a few windows straddle two levels; the GAN's
    training data in the original work came from windows of separate levels, a difference of
    ~55 windows per boundary out of ~7,200.
    """
    full = human_level_array()
    starts = range(0, full.shape[1] - width + 1, stride)
    return np.stack([full[:, s:s + width] for s in starts])
