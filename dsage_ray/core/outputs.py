"""What a run leaves in its folder: metrics, the ground-truth archive, a heatmap, a few elites."""

from __future__ import annotations

import io
import json
import textwrap
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from dsage_ray.io import atomic_write_bytes, atomic_write_json, atomic_write_text, replace_dir, staging_dir
from dsage_ray.types import RenderableDomain

if TYPE_CHECKING:
    from dsage_ray.core.snapshot import RunSnapshot


#: Characters of a title per line that fit a 6-inch figure at the default font size.
_TITLE_CHARS = 60


def heatmap_png(archive, *, title: str = "", measure_names: tuple[str, ...] = (), zoom: bool = False) -> bytes:
    """The ground-truth archive as a PNG heatmap of objective values.

    ``zoom`` shows only the cells the elites occupy, plus a margin (:func:`~dsage_ray.qd.archives.zoom_window`):
    a few hundred elites in a 256×162 grid are otherwise a few specks.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from ribs.visualize import grid_archive_heatmap

    fig, ax = plt.subplots(figsize=(6, 4.5), dpi=100)
    grid_archive_heatmap(archive, ax=ax, cmap="viridis")
    if zoom and len(archive) > 0 and len(archive.dims) == 2:
        from dsage_ray.qd.archives import zoom_window

        cells = np.asarray(archive.int_to_grid_index(archive.data("index")))
        for k, set_limits in enumerate((ax.set_xlim, ax.set_ylim)):
            low, high = zoom_window(int(cells[:, k].min()), int(cells[:, k].max()), int(archive.dims[k]))
            set_limits(archive.boundaries[k][low], archive.boundaries[k][high + 1])
    if len(measure_names) >= 2:
        ax.set_xlabel(measure_names[0])
        ax.set_ylabel(measure_names[1])
    # A title naming a long agent spec would run off the figure: wrap it to the figure's width instead.
    ax.set_title(textwrap.fill(title or f"{len(archive)} elites", width=_TITLE_CHARS))
    fig.tight_layout()
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png")
    plt.close(fig)
    return buffer.getvalue()


def heatmap_image(archive, **kwargs) -> np.ndarray:
    """The heatmap as an ``(H, W, 3)`` uint8 array, e.g. for TensorBoard."""
    from PIL import Image

    return np.asarray(Image.open(io.BytesIO(heatmap_png(archive, **kwargs))).convert("RGB"))


def scatter_png(predicted: np.ndarray, true: np.ndarray, measure_names: tuple[str, ...]) -> bytes:
    """Predicted vs. true measures of the batch just evaluated (the paper's Fig. 9)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(measure_names), figsize=(4 * len(measure_names), 4), dpi=100, squeeze=False)
    for j, (ax, name) in enumerate(zip(axes[0], measure_names)):
        ax.scatter(true[:, j], predicted[:, j], s=6, alpha=0.6)
        low, high = float(min(true[:, j].min(), predicted[:, j].min())), float(max(true[:, j].max(), predicted[:, j].max()))
        ax.plot([low, high], [low, high], "k--", linewidth=0.8)
        ax.set_xlabel(f"true {name}")
        ax.set_ylabel(f"predicted {name}")
    fig.tight_layout()
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png")
    plt.close(fig)
    return buffer.getvalue()


def spread_elites(archive, count: int) -> list[int]:
    """Indices (into ``archive.data()``) of up to ``count`` elites spread along the first measure."""
    data = archive.data()
    n = len(data["objective"])
    if n == 0:
        return []
    order = np.argsort(data["measures"][:, 0], kind="stable")
    picks = np.unique(np.linspace(0, n - 1, num=min(count, n)).round().astype(int))
    return [int(order[p]) for p in picks]


def render_elites(archive, domain, count: int) -> list[tuple[int, bytes]]:
    """``(index into archive.data(), PNG)`` for up to ``count`` elites spread along the first measure,
    each drawn by ``domain.render`` with its occupancy."""
    data = archive.data()
    return [(index, domain.render(data["solution"][index], data["occupancy"][index]))
            for index in spread_elites(archive, count)]


def write_outputs(run: "RunSnapshot", run_dir: str | Path, *, num_elites: int = 6) -> Path:
    """Writes the run folder; every file is written atomically, the elites folder swapped in whole."""
    from dsage_ray.qd.archives import archive_to_dataframe

    run_dir = Path(run_dir)
    run_dir.mkdir(parents=True, exist_ok=True)
    domain = run.domain
    atomic_write_json(run_dir / "config.json", run.config.to_dict())
    atomic_write_json(run_dir / "metrics.json", list(run.history))
    atomic_write_json(run_dir / "failures.json", list(run.failures))
    atomic_write_text(run_dir / "archive.csv", archive_to_dataframe(run.archive).to_csv(index=False))
    atomic_write_bytes(
        run_dir / "heatmap.png",
        heatmap_png(run.archive, title=f"{run.config.name}: {run.evals} evaluations",
                    measure_names=domain.measure_names, zoom=True),
    )
    if isinstance(domain, RenderableDomain):
        staging = staging_dir(run_dir / "elites")
        data = run.archive.data()
        summary = []
        for rank, (index, png) in enumerate(render_elites(run.archive, domain, num_elites)):
            name = f"elite_{rank:02d}.png"
            (staging / name).write_bytes(png)
            summary.append({
                "file": name,
                "objective": float(data["objective"][index]),
                "measures": dict(zip(domain.measure_names, map(float, data["measures"][index]))),
            })
        (staging / "elites.json").write_text(json.dumps(summary, indent=2))
        replace_dir(staging, run_dir / "elites")
    return run_dir
