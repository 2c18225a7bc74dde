"""PNG pictures of Mario levels (coloured tiles) with Mario's path drawn on top."""

from __future__ import annotations

import io
from pathlib import Path
from typing import Sequence

import numpy as np
from PIL import Image, ImageDraw

from dsage_ray.domains.mario.tiles import TILES, to_array

#: One RGB colour per tile index (TILES order); chosen to be told apart at 4 px per tile.
TILE_COLOURS: np.ndarray = np.array([
    (146, 190, 255),  # - empty (sky)
    (40, 40, 40),     # * cannon
    (230, 30, 30),    # y spiky
    (150, 80, 20),    # g goomba
    (30, 160, 30),    # k green koopa
    (200, 40, 90),    # r red koopa
    (0, 200, 0),      # t pipe
    (180, 90, 40),    # S brick
    (250, 200, 0),    # ! coin block
    (255, 140, 0),    # @ power-up block
    (255, 255, 255),  # F flag
    (120, 60, 20),    # X ground
    (210, 170, 120),  # % platform
    (255, 0, 255),    # M start
    (190, 210, 255),  # | platform background
    (255, 230, 60),   # o coin
    (90, 90, 90),     # # solid
], dtype=np.uint8)
assert len(TILE_COLOURS) == len(TILES)

TILE_PX = 16  # the framework's tile size in pixels; agent events are in these units
#: A titled picture's width in inches (a report card shows it at about 330 to 410 px), its resolution and the
#: points of its text.
FIGURE_WIDTH = 3.6
DPI = 200
FONT_SIZE = 11


def render_level(level: np.ndarray | str | Sequence[str], *, scale: int = 8, path: np.ndarray | None = None,
                 occupancy: np.ndarray | None = None,
                 path_colour: tuple[int, int, int] = (255, 0, 0),
                 occupancy_max: float | None = None) -> np.ndarray:
    """Draws a level as an RGB image.

    Args:
        level: Tile-index array or level text.
        scale: Pixels per tile.
        path: Optional ``(ticks, 2)`` array of Mario's ``(x, y)`` positions in framework pixels
            (16 per tile, ``y`` at Mario's feet), e.g. from :class:`~dsage_ray.domains.mario.simulator.EpisodeResult`.
        occupancy: Optional ``(rows, cols)`` ticks per tile (the evaluation's ancillary data);
            visited tiles are tinted toward ``path_colour``, more for more ticks. Used when the
            path itself is not kept (archive elites keep only their occupancy).
        path_colour: RGB of the path line and the occupancy tint.
        occupancy_max: Ticks per tile at which the tint is strongest; pass one value for a whole collection
            so its pictures compare. None: this level's own maximum.

    Returns:
        ``(rows·scale, cols·scale, 3)`` uint8 array.
    """
    tiles = to_array(level) if not isinstance(level, np.ndarray) else np.asarray(level)
    colours = TILE_COLOURS[tiles].astype(np.float32)
    if occupancy is not None:
        occupancy = np.asarray(occupancy, dtype=np.float32)
        if occupancy.shape != tiles.shape:
            raise ValueError(f"occupancy shape {occupancy.shape} does not match the level's {tiles.shape}")
        # Log scale: a tile Mario stood on for 100 ticks should not wash out one he passed once.
        top = float(occupancy.max()) if occupancy_max is None else float(occupancy_max)
        strength = np.minimum(np.log1p(occupancy) / np.log1p(max(top, 1.0)), 1.0)
        alpha = np.where(occupancy > 0, 0.35 + 0.5 * strength, 0.0)
        colours = (1 - alpha[..., None]) * colours + alpha[..., None] * np.array(path_colour, np.float32)
    image = np.repeat(np.repeat(colours.round().astype(np.uint8), scale, axis=0), scale, axis=1)
    if path is None or len(path) == 0:
        return image
    pil = Image.fromarray(image)
    draw = ImageDraw.Draw(pil)
    # Feet are at y; lift the line half a (small-Mario) tile so it runs through Mario's body.
    points = [(float(x) * scale / TILE_PX, (float(y) - TILE_PX / 2) * scale / TILE_PX) for x, y in path]
    if len(points) > 1:
        draw.line(points, fill=path_colour, width=max(1, scale // 4))
    else:
        x, y = points[0]
        draw.ellipse((x - 2, y - 2, x + 2, y + 2), fill=path_colour)
    return np.asarray(pil)


def _titled_png(image: np.ndarray, *, scale: int, title: str) -> bytes:
    """``image`` in a figure with a title and row/column ticks in tiles (the level text's coordinates).

    Drawn for the width a report shows it at (:data:`FIGURE_WIDTH` inches, about 330 to 410 px on the page),
    with :data:`FONT_SIZE`-point text: every label stays at about 14 px or more on the page.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    rows, cols = image.shape[0] // scale, image.shape[1] // scale
    line = FONT_SIZE * 1.4 / 72  # inches per line of text
    image_w = FIGURE_WIDTH - 2.5 * line
    fig = Figure(figsize=(FIGURE_WIDTH, image_w * rows / cols + 4.5 * line), dpi=DPI)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    ax.imshow(image, extent=(-0.5, cols - 0.5, rows - 0.5, -0.5), interpolation="nearest")
    # A tick every 10 columns and 5 rows: the numbers of a 56-column level would run into each other.
    ax.set_xticks(range(0, cols, 10))
    ax.set_yticks(range(0, rows, 5))
    ax.tick_params(labelsize=FONT_SIZE, length=2, pad=1)
    ax.set_xlabel("column", fontsize=FONT_SIZE, labelpad=1)
    ax.set_ylabel("row", fontsize=FONT_SIZE, labelpad=1)
    ax.set_title(title, fontsize=FONT_SIZE)
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", bbox_inches="tight", pad_inches=0.04)
    return buffer.getvalue()


def level_png(level: np.ndarray | str | Sequence[str], *, scale: int = 8, path: np.ndarray | None = None,
              occupancy: np.ndarray | None = None, occupancy_max: float | None = None,
              title: str | None = None) -> bytes:
    """:func:`render_level`'s picture as PNG bytes.

    With a ``title``, the picture sits in a figure with the title and row/column ticks (for reports);
    without, it is the bare tile image (for TensorBoard and level samples).
    """
    image = render_level(level, scale=scale, path=path, occupancy=occupancy, occupancy_max=occupancy_max)
    if title is not None:
        return _titled_png(image, scale=scale, title=title)
    buffer = io.BytesIO()
    Image.fromarray(image).save(buffer, format="PNG")
    return buffer.getvalue()


def save_level_png(level: np.ndarray | str | Sequence[str], out: str | Path, *, scale: int = 8,
                   path: np.ndarray | None = None, occupancy: np.ndarray | None = None,
                   occupancy_max: float | None = None, title: str | None = None) -> Path:
    """Writes :func:`level_png` to ``out`` and returns the path."""
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_bytes(level_png(level, scale=scale, path=path, occupancy=occupancy, occupancy_max=occupancy_max,
                              title=title))
    return out
