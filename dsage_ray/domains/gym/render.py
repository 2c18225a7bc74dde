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

#: Points of every text in the picture: shown at about half its pixel width in the report, 12 pt stays >= 10 px.
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
    """A PNG: the first frame, the occupancy histogram (when the space declares coordinates) and the numbers.

    Args:
        space: The level's space.
        values: ``{parameter name: value}``.
        occupancy: The evaluation's histogram.
        title: Shown above the panels.
        occupancy_max: Top of the histogram's colour scale (one value for a whole collection).
        result: The evaluation, whose returns and success are listed beside the parameters.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    frame = first_frame(space, values)
    show_occupancy = bool(space.occupancy) and occupancy is not None
    panels = [p for p, shown in (("frame", frame is not None), ("occupancy", show_occupancy), ("text", True)) if shown]
    widths = {"frame": 3.6, "occupancy": 3.4, "text": 3.2}
    fig = Figure(figsize=(sum(widths[p] for p in panels), 3.4), dpi=100)
    FigureCanvasAgg(fig)
    axes = fig.subplots(1, len(panels), gridspec_kw={"width_ratios": [widths[p] for p in panels]}, squeeze=False)[0]
    for ax, panel in zip(axes, panels):
        if panel == "frame":
            ax.imshow(frame)
            ax.set_axis_off()
            ax.set_title("first frame", fontsize=FONT_SIZE)
        elif panel == "occupancy":
            x, y = space.occupancy
            grid = np.asarray(occupancy, dtype=float)
            image = ax.imshow(grid.T, origin="lower", aspect="auto", cmap="YlOrRd", vmin=0,
                              vmax=occupancy_max or max(float(grid.max()), 1e-9),
                              extent=(x.low, x.high, y.low, y.high))
            ax.set_xlabel(x.signal.describe().replace(" at the end", ""), fontsize=FONT_SIZE)
            ax.set_ylabel(y.signal.describe().replace(" at the end", ""), fontsize=FONT_SIZE)
            ax.tick_params(labelsize=FONT_SIZE - 1)
            ax.set_title("time spent", fontsize=FONT_SIZE)
            colorbar = fig.colorbar(image, ax=ax, fraction=0.08)
            colorbar.ax.tick_params(labelsize=FONT_SIZE - 2)
        else:
            ax.set_axis_off()
            lines = [f"{name} = {_short(value)}" for name, value in values.items()]
            if result is not None and "mean_return" in result.info:
                lines += ["", f"failure rate {result.objective:.2f}", f"mean return {result.info['mean_return']:.1f}",
                          f"worst return {result.info['min_return']:.1f}",
                          f"mean length {result.info['mean_length']:.0f}"]
            ax.text(0.0, 1.0, "\n".join(lines), va="top", ha="left", fontsize=FONT_SIZE, family="monospace",
                    transform=ax.transAxes)
    fig.suptitle(title or space.env_id, fontsize=FONT_SIZE + 1)
    fig.tight_layout()
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png")
    return buffer.getvalue()


def _short(value: Any) -> str:
    return f"{value:.3g}" if isinstance(value, float) else str(value)
