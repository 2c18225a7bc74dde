"""The picture of a gym level: the environment's first frame with the level's parameters, where the agent went
(the occupancy histogram of the space's two coordinates) and the level's numbers, legible at report size."""

from __future__ import annotations

import io
import os
import warnings
from typing import Any, Mapping

import numpy as np

from dsage_ray.domains.gym.space import EnvSpace
from dsage_ray.types import EvaluationResult

#: The picture's width in inches: a report card shows it at about 330 to 410 px, so an inch is about 100 px on
#: the page, and the resolution that keeps it sharp on a high-density screen.
FIGURE_WIDTH = 3.6
DPI = 200
#: Points of the titles and axis labels; the tick labels are a point smaller, still 14 px or more on the page.
FONT_SIZE = 12


def first_frame(space: EnvSpace, values: Mapping[str, Any]) -> np.ndarray | None:
    """The environment's ``rgb_array`` frame right after reset with the level's values, or None when it has none."""
    from dsage_ray.domains.gym.simulator import make_env, reset_env

    # pygame draws the frames off screen; without these it looks for a display and a sound card and says so.
    os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
    os.environ.setdefault("SDL_AUDIODRIVER", "dummy")
    try:
        env = make_env(space, values, render_mode="rgb_array")
    except Exception:  # noqa: BLE001 - an environment without rgb_array rendering still gets the other panels
        return None
    try:
        reset_env(env, space, values, seed=0)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            frame = env.render()
        return np.asarray(frame) if frame is not None and np.ndim(frame) == 3 else None
    except Exception:  # noqa: BLE001
        return None
    finally:
        env.close()


def level_picture(space: EnvSpace, values: Mapping[str, Any], *, occupancy: np.ndarray | None = None,
                  title: str | None = None, occupancy_max: float | None = None,
                  result: EvaluationResult | None = None) -> bytes:
    """A PNG, one panel above the other so that it stays legible in a report card about 330 px wide: the first
    frame (with the level's parameters set), the occupancy histogram (when the space declares coordinates), and,
    without either, the parameter values as text.

    Args:
        space: The level's space.
        values: ``{parameter name: value}``.
        occupancy: The evaluation's histogram.
        title: Shown above the panels.
        occupancy_max: Top of the histogram's colour scale (one value for a whole collection).
        result: The evaluation (its failure rate joins the title).
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.colors import PowerNorm
    from matplotlib.figure import Figure

    frame = first_frame(space, values)
    show_occupancy = bool(space.occupancy) and occupancy is not None
    panels = [p for p, shown in (("frame", frame is not None), ("occupancy", show_occupancy)) if shown] or ["text"]
    heights = {"frame": 2.2, "occupancy": 2.9, "text": 0.4 + 0.22 * len(values)}
    fig = Figure(figsize=(FIGURE_WIDTH, 0.5 + sum(heights[p] for p in panels)), dpi=DPI)
    FigureCanvasAgg(fig)
    axes = fig.subplots(len(panels), 1, gridspec_kw={"height_ratios": [heights[p] for p in panels]}, squeeze=False)
    for ax, panel in zip(axes[:, 0], panels):
        if panel == "frame":
            ax.imshow(_crop(frame))
            ax.set_axis_off()
        elif panel == "occupancy":
            x, y = space.occupancy
            grid = np.asarray(occupancy, dtype=float)
            # A square-root scale: one collection's scale tops at its busiest level (a taxi circling two cells for
            # the whole episode), and a short episode's path must still show beside it.
            image = ax.imshow(grid.T, origin="lower", aspect="auto", cmap="YlOrRd",
                              norm=PowerNorm(0.5, vmin=0, vmax=occupancy_max or max(float(grid.max()), 1e-9)),
                              extent=(x.low, x.high, y.low, y.high))
            ax.set_xlabel(x.label, fontsize=FONT_SIZE)
            ax.set_ylabel(y.label, fontsize=FONT_SIZE)
            ax.tick_params(labelsize=FONT_SIZE - 1)
            ax.set_title("share of the time spent", fontsize=FONT_SIZE)
            colorbar = fig.colorbar(image, ax=ax, fraction=0.08)
            colorbar.ax.tick_params(labelsize=FONT_SIZE - 1)
        else:
            ax.set_axis_off()
            ax.text(0.0, 1.0, "\n".join(f"{name} = {_short(value)}" for name, value in values.items()), va="top",
                    ha="left", fontsize=FONT_SIZE, family="monospace", transform=ax.transAxes)
    if title is None and result is not None:
        title = f"failure rate {result.objective:.2f}"
    fig.suptitle(title or space.env_id, fontsize=FONT_SIZE)
    fig.tight_layout()
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png")
    return buffer.getvalue()


def _crop(frame: np.ndarray) -> np.ndarray:
    """The frame without its uniform border rows and columns (CartPole's track sits in a mostly white frame)."""
    background = frame[0, 0]
    content = np.any(frame != background, axis=2)
    rows, cols = np.flatnonzero(content.any(axis=1)), np.flatnonzero(content.any(axis=0))
    if not len(rows) or not len(cols):
        return frame
    pad = 8
    return frame[max(rows[0] - pad, 0):rows[-1] + pad + 1, max(cols[0] - pad, 0):cols[-1] + pad + 1]


def _short(value: Any) -> str:
    return f"{value:.3g}" if isinstance(value, float) else str(value)
