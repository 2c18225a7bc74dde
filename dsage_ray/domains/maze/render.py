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
    from matplotlib.colors import ListedColormap, PowerNorm
    from matplotlib.figure import Figure

    height, width = level.walls.shape
    walls = np.pad(level.walls, 1, constant_values=True)
    cell = 0.32  # inches per cell
    fig = Figure(figsize=(cell * (width + 2) + (1.6 if occupancy is not None else 0.5), cell * (height + 2) + 0.9),
                 dpi=100)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
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
        bar = fig.colorbar(image, ax=ax, fraction=0.046, pad=0.03)
        bar.set_label("visits per episode", fontsize=10)
        bar.ax.tick_params(labelsize=9)
    # Thin cell lines on the floor make rows and columns countable; walls hide them.
    ax.set_xticks(np.arange(-1.5, width + 1), minor=True)
    ax.set_yticks(np.arange(-1.5, height + 1), minor=True)
    ax.grid(which="minor", color="#d0d0d0", linewidth=0.5)
    ax.tick_params(which="minor", length=0)
    ax.set_xticks(range(width))
    ax.set_yticks(range(height))
    ax.tick_params(labelsize=7, length=2, pad=1, top=True, labeltop=True, bottom=False, labelbottom=False)
    for cell_pos, mark, colour in ((level.start, "S", "#1f5fbf"), (level.goal, "G", "#138a36")):
        if cell_pos is not None:
            ax.text(cell_pos[1], cell_pos[0], mark, ha="center", va="center", fontsize=10, fontweight="bold",
                    color="white", bbox={"boxstyle": "square,pad=0.12", "facecolor": colour, "edgecolor": "none"})
    if title:
        ax.set_title(title, fontsize=11, pad=18)
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", bbox_inches="tight")
    data = buffer.getvalue()
    if path is not None:
        Path(path).write_bytes(data)
    return data
