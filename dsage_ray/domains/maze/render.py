"""PNG pictures of Maze levels with an optional occupancy heat overlay.

Drawn for the size a report shows them at: :data:`FIGURE_WIDTH` inches wide (about 330 to 410 px on the page,
so an inch is about 100 screen pixels) at :data:`DPI` dots per inch (sharp on a high-density screen), with text
of at least :data:`FONT_SIZE` points, which keeps every label at about 14 px or more on the page.
"""

from __future__ import annotations

import io
import textwrap
from pathlib import Path

import numpy as np

from dsage_ray.domains.maze.level import MazeLevel


#: Walls (and the border) near-black, floor white: nothing in the visit colormap comes close to either.
WALL_COLOUR = "#262626"
FLOOR_COLOUR = "white"
#: Visits: the light-to-warm part of YlOrRd (pale yellow to red), cut before its dark maroon end so the
#: most-visited cells, the loops that explain a failure, can never be mistaken for walls.
VISIT_CMAP_RANGE = (0.12, 0.82)
#: Width of every picture in inches, whatever the maze's size: the report shows it at one card's width.
FIGURE_WIDTH = 3.6
DPI = 200
#: Points of the labels (ticks, colour bar, title); the S and G marks shrink to fit a cell of a large maze.
FONT_SIZE = 11
#: Rows and columns are numbered every this many cells: every cell's number would not fit at this size.
TICK_EVERY = 5


def _visit_cmap():
    from matplotlib import colormaps
    from matplotlib.colors import ListedColormap

    return ListedColormap(colormaps["YlOrRd"](np.linspace(*VISIT_CMAP_RANGE, 256)), name="visits")


def _wrapped(title: str) -> list[str]:
    """``title`` in lines that fit the picture's width (a path in the title would otherwise run off it)."""
    chars_per_line = int(FIGURE_WIDTH * 72 / (0.6 * FONT_SIZE))  # a DejaVu Sans character is about 0.6 em wide
    return textwrap.wrap(title, chars_per_line, break_long_words=True) or [""]


def _bar_ticks(top: float) -> list[float]:
    """Three colour-bar ticks: none, the middle of the square-root scale (a quarter of the top) and the top.

    More would crowd the top of a square-root scale, where the values lie close together.
    """
    return [0.0, top / 4, top] if top > 0 else [0.0]


def render_level(level: MazeLevel, occupancy: np.ndarray | None = None, path: str | Path | None = None,
                 *, title: str | None = None, occupancy_max: float | None = None) -> bytes:
    """Draws walls (with the border), start (S), goal (G) and, optionally, occupancy as a heat map.

    Rows and columns are ticked in the interior coordinates that layouts and ``(row, col)`` positions use.
    The colour bar lies under the maze, so the maze takes the picture's whole width.

    Args:
        level: The level.
        occupancy: ``(H, W)`` expected visits per cell, e.g. ``MazeEvaluation.occupancy``.
        path: Where to write the PNG, if anywhere.
        title: Optional figure title (wrapped to the picture's width).
        occupancy_max: Top of the visit colour scale; pass one value for a whole collection so its pictures
            compare. None: this level's own maximum.

    Returns:
        The PNG bytes.
    """
    # The object-oriented API with an Agg canvas: no pyplot global state, safe in worker threads.
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.collections import LineCollection
    from matplotlib.colors import ListedColormap
    from matplotlib.figure import Figure

    height, width = level.walls.shape
    walls = np.pad(level.walls, 1, constant_values=True)
    # Every margin is placed in inches, so one draw makes the picture: ``bbox_inches="tight"`` would draw it
    # twice, and drawing is most of what an audit of a few hundred levels spends on its pictures.
    line = FONT_SIZE * 1.35 / 72  # inches per line of text
    left, right = 2.6 * line, 0.1
    cell = (FIGURE_WIDTH - left - right) / (width + 2)
    grid_w, grid_h = cell * (width + 2), cell * (height + 2)
    title_lines = _wrapped(title) if title else []
    top = 0.08 + 1.3 * line + len(title_lines) * line  # the column numbers, then the title
    bar = 2.6 * line if occupancy is not None else 0.0  # bar, its numbers and its label
    bottom = 0.08 + bar
    fig = Figure(figsize=(FIGURE_WIDTH, bottom + grid_h + top), dpi=DPI)
    FigureCanvasAgg(fig)
    fig_w, fig_h = fig.get_size_inches()
    if title_lines:
        fig.text(0.5, 1.0 - 0.06 / fig_h, "\n".join(title_lines), ha="center", va="top", fontsize=FONT_SIZE,
                 linespacing=1.2)
    ax = fig.add_axes((left / fig_w, bottom / fig_h, grid_w / fig_w, grid_h / fig_h))
    extent = (-1.5, width + 0.5, height + 0.5, -1.5)  # interior (row, col) coordinates, border at -1
    ax.imshow(walls, cmap=ListedColormap([FLOOR_COLOUR, WALL_COLOUR]), vmin=0, vmax=1, extent=extent,
              interpolation="nearest")
    if occupancy is not None:
        # The bar is inset from the maze's sides, so its first and last numbers, centred on its ends, fit.
        inset = 0.25
        _draw_occupancy(fig, ax, occupancy, (height, width), occupancy_max,
                        ((left + inset) / fig_w, (bottom - 1.1 * line) / fig_h, (grid_w - 2 * inset) / fig_w,
                         0.09 / fig_h))
    # Thin cell lines on the floor make rows and columns countable; walls hide them.
    # Drawn as one collection rather than as minor-tick grid lines: ticks cost most of a picture's time.
    lines = [[(x, -1.5), (x, height + 0.5)] for x in np.arange(-1.5, width + 1)]
    lines += [[(-1.5, y), (width + 0.5, y)] for y in np.arange(-1.5, height + 1)]
    ax.add_collection(LineCollection(lines, colors="#d0d0d0", linewidths=0.4, zorder=1.5))
    ax.set_xticks(range(0, width, TICK_EVERY))
    ax.set_yticks(range(0, height, TICK_EVERY))
    ax.tick_params(labelsize=FONT_SIZE, length=2, pad=1, top=True, labeltop=True, bottom=False, labelbottom=False)
    # The marks fill most of a cell (about 10 pt in the Maze's 16 x 16 levels), smaller in larger mazes.
    mark_size = min(FONT_SIZE, 0.75 * cell * 72)
    for cell_pos, mark, colour in ((level.start, "S", "#1f5fbf"), (level.goal, "G", "#138a36")):
        if cell_pos is not None:
            ax.text(cell_pos[1], cell_pos[0], mark, ha="center", va="center", fontsize=mark_size, fontweight="bold",
                    color="white", bbox={"boxstyle": "square,pad=0.12", "facecolor": colour, "edgecolor": "none"})
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png")
    data = buffer.getvalue()
    if path is not None:
        Path(path).write_bytes(data)
    return data


def _draw_occupancy(fig, ax, occupancy: np.ndarray, shape: tuple[int, int], occupancy_max: float | None,
                    bar_rect: tuple[float, float, float, float]) -> None:
    """The visits over the maze's floor and their colour bar, horizontal at ``bar_rect`` (figure fractions)."""
    from matplotlib.colors import PowerNorm

    occupancy = np.asarray(occupancy, dtype=np.float64)
    if occupancy.shape != shape:
        raise ValueError(f"occupancy has shape {occupancy.shape}, expected {shape}")
    top = float(occupancy_max) if occupancy_max is not None else float(occupancy.max())
    # Unvisited cells stay plain floor; a square-root scale keeps cells passed once visible next to loops.
    heat = np.ma.masked_where(np.pad(occupancy, 1) <= 0, np.pad(occupancy, 1))
    image = ax.imshow(heat, cmap=_visit_cmap(), norm=PowerNorm(0.5, vmin=0.0, vmax=max(top, 1e-9), clip=True),
                      extent=ax.get_images()[0].get_extent(), interpolation="nearest")
    bar = fig.colorbar(image, cax=fig.add_axes(bar_rect), orientation="horizontal", ticks=_bar_ticks(top))
    bar.ax.set_xticklabels([f"{t:.3g}" for t in _bar_ticks(top)])
    bar.set_label("visits per episode", fontsize=FONT_SIZE, labelpad=1)
    bar.ax.tick_params(labelsize=FONT_SIZE, length=2, pad=1)
