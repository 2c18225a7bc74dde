"""The collection's levels as archive heatmaps, the pictures at the top of its page."""

from __future__ import annotations

import io
from typing import Any

import numpy as np

from dsage_ray.audit.report.statistics import objective_label
from dsage_ray.audit.summary import grid_indices
from dsage_ray.qd.archives import zoom_window

#: The narrowest the page shows a picture: a worst-level card on a 390 px phone. The pictures' text is sized
#: for it (the domains' ``render`` modules): about 13 px or more there, larger wherever a card is wider.
PICTURE_MIN_WIDTH = 330


def heatmap_pngs(collection: dict[str, Any]) -> dict[str, bytes]:
    """The collection's levels as archive heatmaps over the first two measures: ``zoomed`` to the cells the
    levels occupy (plus a margin) and ``full`` over the measures' whole ranges, one colour scale for both.

    Each cell shows the highest objective among its levels (a regression audit: the largest regression, as
    its [0, 1] score). Empty when there are no levels or fewer than two measures.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    levels, measures = collection["levels"], collection["measures"]
    if not levels or len(measures) < 2:
        return {}
    ranges = np.asarray(collection["measure_ranges"], dtype=float)[:2]
    dims = [int(d) for d in collection["archive_dims"][:2]]
    values = np.array([[lv["measures"][m] for m in measures[:2]] for lv in levels], dtype=float)
    cells = grid_indices(values, ranges=ranges, dims=dims)
    grid = np.full(dims, np.nan)
    for (i, j), lv in zip(cells.tolist(), levels):
        grid[i, j] = lv["objective"] if np.isnan(grid[i, j]) else max(grid[i, j], lv["objective"])
    low, high = float(np.nanmin(grid)), float(np.nanmax(grid))
    vmin = min(0.0, low)
    vmax = high if high > vmin else vmin + 1.0
    edges = [np.linspace(lo, hi, d + 1) for (lo, hi), d in zip(ranges, dims)]
    occupied = [(int(cells[:, k].min()), int(cells[:, k].max())) for k in range(2)]

    label = objective_label(collection)

    def draw(window: list[tuple[int, int]], title: str) -> bytes:
        # Sized like the level pictures, for the page: 4.2 in wide is shown 366 px wide on a phone and at most
        # 620 px on a wide screen; 12 pt stays 13 px or more on the page.
        fig = Figure(figsize=(4.2, 3.4), dpi=160)
        FigureCanvasAgg(fig)
        ax = fig.add_subplot()
        ax.set_facecolor("#ececec")  # empty cells
        mesh = ax.pcolormesh(edges[0], edges[1], np.ma.masked_invalid(grid.T), cmap="viridis", vmin=vmin,
                             vmax=vmax)
        ax.set_xlim(edges[0][window[0][0]], edges[0][window[0][1] + 1])
        ax.set_ylim(edges[1][window[1][0]], edges[1][window[1][1] + 1])
        # Names from the collection file are text, not mathtext ("$" in a name would be parsed).
        ax.set_xlabel(measures[0], fontsize=12, parse_math=False)
        ax.set_ylabel(measures[1], fontsize=12, parse_math=False)
        ax.tick_params(labelsize=12)
        ax.set_title(title, fontsize=12)
        bar = fig.colorbar(mesh, ax=ax)
        bar.set_label(label, fontsize=12, parse_math=False)
        bar.ax.tick_params(labelsize=12)
        fig.tight_layout(pad=0.3)
        buffer = io.BytesIO()
        fig.savefig(buffer, format="png")
        return buffer.getvalue()

    zoom = [zoom_window(lo, hi, d) for (lo, hi), d in zip(occupied, dims)]
    return {"zoomed": draw(zoom, f"Zoomed to the {len(levels)} levels"),
            "full": draw([(0, dims[0] - 1), (0, dims[1] - 1)], "Full measure range")}
