"""The run folder's and TensorBoard's heatmap zooms to the cells the elites occupy."""

from __future__ import annotations

import io

import numpy as np
from PIL import Image

from dsage_ray.core.outputs import heatmap_png
from dsage_ray.qd.archives import make_archive


def test_a_zoomed_heatmap_spends_its_pixels_on_the_occupied_cells():
    archive = make_archive(solution_dim=4, dims=(256, 162), ranges=[(0, 256), (0, 648)], seed=0)
    rng = np.random.default_rng(0)
    measures = np.column_stack([rng.uniform(100, 120, 30), rng.uniform(200, 260, 30)])
    archive.add(rng.random((30, 4)), rng.random(30), measures)

    def coloured_share(png: bytes) -> float:
        """Share of the plot's pixels (the colour bar on the right left out) that are coloured: filled cells."""
        pixels = np.asarray(Image.open(io.BytesIO(png)).convert("RGB")).astype(int)
        pixels = pixels[:, : int(pixels.shape[1] * 0.78)]
        spread = pixels.max(axis=2) - pixels.min(axis=2)
        return float(np.mean(spread > 40))

    full, zoomed = heatmap_png(archive), heatmap_png(archive, zoom=True)
    assert coloured_share(zoomed) > 5 * coloured_share(full)


def test_a_long_title_is_wrapped_inside_the_heatmap(monkeypatch):
    import matplotlib.pyplot as plt

    titles = []  # (text, its box, the figure's box), read as the heatmap closes its figure
    close = plt.close

    def read_then_close(figure):
        title = figure.axes[0].title
        titles.append((title.get_text(), title.get_window_extent(figure.canvas.get_renderer()), figure.bbox))
        close(figure)

    monkeypatch.setattr(plt, "close", read_then_close)
    archive = make_archive(solution_dim=2, dims=(10, 10), ranges=[(0, 1), (0, 1)], seed=0)
    archive.add(np.full((1, 2), 0.5), np.ones(1), np.full((1, 2), 0.5))
    title = "failure_rate of rllib:ppo_lunarlander?greedy=1 against rllib:ppo_lunarlander_old (203 levels, re-evaluated)"
    heatmap_png(archive, title=title)

    ((shown, box, page),) = titles
    assert shown.replace("\n", " ") == title
    assert page.x0 <= box.x0 and box.x1 <= page.x1 and box.y1 <= page.y1
