"""PNG pictures of Maze levels with an optional occupancy heat overlay."""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np

from dsage_ray.domains.maze.level import MazeLevel


def render_level(level: MazeLevel, occupancy: np.ndarray | None = None, path: str | Path | None = None,
                 *, title: str | None = None) -> bytes:
    """Draws walls (with the border), start (S), goal (G) and, optionally, occupancy as a heat map.

    Args:
        level: The level.
        occupancy: ``(H, W)`` expected visits per cell, e.g. ``MazeEvaluation.occupancy``.
        path: Where to write the PNG, if anywhere.
        title: Optional figure title.

    Returns:
        The PNG bytes.
    """
    # The object-oriented API with an Agg canvas: no pyplot global state, safe in worker threads.
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.colors import ListedColormap
    from matplotlib.figure import Figure

    height, width = level.walls.shape
    walls = np.pad(level.walls, 1, constant_values=True)
    fig = Figure(figsize=(0.3 * (width + 2) + 1.2, 0.3 * (height + 2) + 0.4), dpi=100)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    extent = (-1.5, width + 0.5, height + 0.5, -1.5)  # interior (row, col) coordinates, border at -1
    ax.imshow(walls, cmap=ListedColormap(["white", "#404040"]), vmin=0, vmax=1, extent=extent,
              interpolation="nearest")
    if occupancy is not None:
        occupancy = np.asarray(occupancy, dtype=np.float64)
        if occupancy.shape != (height, width):
            raise ValueError(f"occupancy has shape {occupancy.shape}, expected {(height, width)}")
        heat = np.ma.masked_where(np.pad(occupancy, 1) <= 0, np.pad(occupancy, 1))
        image = ax.imshow(heat, cmap="inferno_r", alpha=0.75, extent=extent, interpolation="nearest")
        fig.colorbar(image, ax=ax, fraction=0.046, pad=0.04, label="visits per episode")
    for cell, mark, colour in ((level.start, "S", "tab:blue"), (level.goal, "G", "tab:green")):
        if cell is not None:
            ax.text(cell[1], cell[0], mark, ha="center", va="center", fontsize=9, fontweight="bold", color="white",
                    bbox={"boxstyle": "square,pad=0.15", "facecolor": colour, "edgecolor": "none"})
    ax.set_xticks([])
    ax.set_yticks([])
    if title:
        ax.set_title(title, fontsize=9)
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", bbox_inches="tight")
    data = buffer.getvalue()
    if path is not None:
        Path(path).write_bytes(data)
    return data
