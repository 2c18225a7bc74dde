"""PNG pictures of Maze levels with an optional occupancy heat overlay."""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np

from dsage_ray.domains.maze.level import MazeLevel


#: Walls (and the border) near-black, floor white: nothing in the visit colormap comes close to either.
WALL_COLOUR = "#262626"
FLOOR_COLOUR = "white"
#: Visits: the light-to-warm part of YlOrRd (pale yellow to red), cut before its dark maroon end so the
#: most-visited cells, the loops that explain a failure, can never be mistaken for walls.
VISIT_CMAP_RANGE = (0.12, 0.82)


def _visit_cmap():
    from matplotlib import colormaps
    from matplotlib.colors import ListedColormap

    return ListedColormap(colormaps["YlOrRd"](np.linspace(*VISIT_CMAP_RANGE, 256)), name="visits")


def render_level(level: MazeLevel, occupancy: np.ndarray | None = None, path: str | Path | None = None,
                 *, title: str | None = None, occupancy_max: float | None = None) -> bytes:
    """Draws walls (with the border), start (S), goal (G) and, optionally, occupancy as a heat map.

    Rows and columns are ticked in the interior coordinates that layouts and ``(row, col)`` positions use.

    Args:
        level: The level.
        occupancy: ``(H, W)`` expected visits per cell, e.g. ``MazeEvaluation.occupancy``.
        path: Where to write the PNG, if anywhere.
        title: Optional figure title.
        occupancy_max: Top of the visit colour scale; pass one value for a whole collection so its pictures
            compare. None: this level's own maximum.

    Returns:
        The PNG bytes.
    """
    # The object-oriented API with an Agg canvas: no pyplot global state, safe in worker threads.
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.collections import LineCollection
    from matplotlib.colors import ListedColormap, PowerNorm
    from matplotlib.figure import Figure

    height, width = level.walls.shape
    walls = np.pad(level.walls, 1, constant_values=True)
    # Every margin is placed in inches, so one draw makes the picture: ``bbox_inches="tight"`` would draw it
    # twice, and drawing is most of what an audit of a few hundred levels spends on its pictures.
    cell = 0.32  # inches per cell
    grid_w, grid_h = cell * (width + 2), cell * (height + 2)
    left, right = 0.3, (1.1 if occupancy is not None else 0.1)
    bottom, top = 0.12, (0.58 if title else 0.28)
    fig = Figure(figsize=(left + grid_w + right, bottom + grid_h + top), dpi=100)
    FigureCanvasAgg(fig)
    title_text = None
    if title:
        title_text = fig.text(0.5, 1.0, title, ha="center", va="top", fontsize=11)
        title_w = title_text.get_window_extent(fig.canvas.get_renderer()).width / fig.dpi + 0.2
        if title_w > fig.get_figwidth():
            # A title wider than the maze widens the picture instead of being cut.
            spare = title_w - fig.get_figwidth()
            left, right = left + spare / 2, right + spare / 2
            fig.set_size_inches(title_w, fig.get_figheight())
    fig_w, fig_h = fig.get_size_inches()
    if title_text is not None:
        title_text.set_y(1.0 - 0.1 / fig_h)
    ax = fig.add_axes((left / fig_w, bottom / fig_h, grid_w / fig_w, grid_h / fig_h))
    extent = (-1.5, width + 0.5, height + 0.5, -1.5)  # interior (row, col) coordinates, border at -1
    ax.imshow(walls, cmap=ListedColormap([FLOOR_COLOUR, WALL_COLOUR]), vmin=0, vmax=1, extent=extent,
              interpolation="nearest")
    if occupancy is not None:
        occupancy = np.asarray(occupancy, dtype=np.float64)
        if occupancy.shape != (height, width):
            raise ValueError(f"occupancy has shape {occupancy.shape}, expected {(height, width)}")
        top = float(occupancy_max) if occupancy_max is not None else float(occupancy.max())
        # Unvisited cells stay plain floor; a square-root scale keeps cells passed once visible next to loops.
        heat = np.ma.masked_where(np.pad(occupancy, 1) <= 0, np.pad(occupancy, 1))
        image = ax.imshow(heat, cmap=_visit_cmap(), norm=PowerNorm(0.5, vmin=0.0, vmax=max(top, 1e-9), clip=True),
                          extent=extent, interpolation="nearest")
        bar_axes = fig.add_axes(((left + grid_w + 0.15) / fig_w, bottom / fig_h, 0.2 / fig_w, grid_h / fig_h))
        bar = fig.colorbar(image, cax=bar_axes)
        bar.set_label("visits per episode", fontsize=10)
        bar.ax.tick_params(labelsize=9)
    # Thin cell lines on the floor make rows and columns countable; walls hide them.
    # Drawn as one collection rather than as minor-tick grid lines: ticks cost most of a picture's time.
    lines = [[(x, -1.5), (x, height + 0.5)] for x in np.arange(-1.5, width + 1)]
    lines += [[(-1.5, y), (width + 0.5, y)] for y in np.arange(-1.5, height + 1)]
    ax.add_collection(LineCollection(lines, colors="#d0d0d0", linewidths=0.5, zorder=1.5))
    ax.set_xticks(range(width))
    ax.set_yticks(range(height))
    ax.tick_params(labelsize=7, length=2, pad=1, top=True, labeltop=True, bottom=False, labelbottom=False)
    for cell_pos, mark, colour in ((level.start, "S", "#1f5fbf"), (level.goal, "G", "#138a36")):
        if cell_pos is not None:
            ax.text(cell_pos[1], cell_pos[0], mark, ha="center", va="center", fontsize=10, fontweight="bold",
                    color="white", bbox={"boxstyle": "square,pad=0.12", "facecolor": colour, "edgecolor": "none"})
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png")
    data = buffer.getvalue()
    if path is not None:
        Path(path).write_bytes(data)
    return data
