"""Self-contained HTML pages for a collection (``report.html``) and an agent comparison.

Images of the heatmap and the worst levels are embedded as base64 so the page shows them wherever it
is opened; the full level table links to the collection's own files by relative path.
"""

from __future__ import annotations

import base64
import html
import os
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from dsage_ray.io import atomic_write_text

#: Levels shown with their picture at the top of a report.
WORST_SHOWN = 12
#: Regions per measure in the per-region statistics.
REGIONS_PER_MEASURE = 4

_STYLE = """
body { font-family: system-ui, sans-serif; margin: 2em; color: #222; }
table { border-collapse: collapse; margin: 1em 0; font-size: 0.9em; }
th, td { border: 1px solid #ccc; padding: 3px 8px; text-align: right; }
th { background: #f0f0f0; }
td.l, th.l { text-align: left; }
.grid { display: flex; flex-wrap: wrap; gap: 1em; }
.card { border: 1px solid #ddd; padding: 0.5em; font-size: 0.85em; }
.card img { width: 280px; }
.worse { background: #fde0dc; } .better { background: #e0f5e0; }
code { background: #f5f5f5; padding: 1px 4px; }
"""


def _img(path: Path, *, width: int | None = None) -> str:
    data = base64.b64encode(path.read_bytes()).decode("ascii")
    style = f' style="width:{width}px"' if width else ""
    return f'<img src="data:image/png;base64,{data}" alt="{html.escape(path.name)}"{style}>'


def _table(headers: Sequence[str], rows: Sequence[Sequence[Any]], *, left: int = 0,
           row_classes: Sequence[str] | None = None) -> str:
    head = "".join(f'<th class="{"l" if i < left else ""}">{html.escape(h)}</th>' for i, h in enumerate(headers))
    body = []
    for r, row in enumerate(rows):
        cls = f' class="{row_classes[r]}"' if row_classes and row_classes[r] else ""
        cells = "".join(f'<td class="{"l" if i < left else ""}">{c}</td>' for i, c in enumerate(row))
        body.append(f"<tr{cls}>{cells}</tr>")
    return f"<table><tr>{head}</tr>{''.join(body)}</table>"


def _page(title: str, body: str) -> str:
    return (f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>{html.escape(title)}</title>"
            f"<style>{_STYLE}</style></head><body><h1>{html.escape(title)}</h1>{body}</body></html>\n")


def region_statistics(levels: Sequence[dict[str, Any]], measures: Sequence[str],
                      *, bins: int = REGIONS_PER_MEASURE) -> list[dict[str, Any]]:
    """Levels grouped by measure region (equal-width bins over the observed range of each measure).

    Returns:
        One record per non-empty region: ``ranges`` per measure, ``levels``, mean ``objective``, mean and
        min ``success_rate``, mean ``mean_path_length`` and the ``worst`` level id; worst regions first.
    """
    if not levels:
        return []
    values = np.array([[lv["measures"][m] for m in measures] for lv in levels], dtype=float)
    edges = [np.linspace(values[:, j].min(), values[:, j].max() + 1e-9, bins + 1) for j in range(len(measures))]
    keys = np.stack([np.clip(np.searchsorted(e, values[:, j], side="right") - 1, 0, bins - 1)
                     for j, e in enumerate(edges)], axis=1)
    regions = []
    for key in sorted({tuple(k) for k in keys.tolist()}):
        members = [lv for lv, k in zip(levels, keys.tolist()) if tuple(k) == key]
        worst = max(members, key=lambda lv: (lv["objective"], lv["mean_path_length"]))
        regions.append({
            "ranges": {m: (float(edges[j][key[j]]), float(edges[j][key[j] + 1])) for j, m in enumerate(measures)},
            "levels": len(members),
            "objective": float(np.mean([lv["objective"] for lv in members])),
            "success_rate": float(np.mean([lv["success_rate"] for lv in members])),
            "min_success_rate": float(min(lv["success_rate"] for lv in members)),
            "mean_path_length": float(np.mean([lv["mean_path_length"] for lv in members])),
            "worst": worst["id"],
        })
    regions.sort(key=lambda r: -r["objective"])
    return regions


def write_report(collection_dir: str | Path) -> Path:
    """Writes ``report.html`` for the collection in ``collection_dir``; returns its path."""
    from dsage_ray.audit.collection import load_collection

    collection_dir = Path(collection_dir)
    c = load_collection(collection_dir)
    levels, measures = c["levels"], c["measures"]
    failing = [lv for lv in levels if lv["success_rate"] < 1.0]
    parts = [
        f"<p>Agent <code>{html.escape(c['agent'])}</code>; objective <b>{html.escape(c['objective'])}</b>; "
        f"measures {', '.join(map(html.escape, measures))}. {len(levels)} valid levels from "
        f"{c['search_elites']} search elites, each re-evaluated for {c['episodes']} episodes with its recorded seed "
        f"({len(failing)} with at least one failed episode). Created {html.escape(c['created'])}.</p>",
        "<p>Reproduce any row: <code>dsage-ray maze eval --agent "
        f"{html.escape(c['agent'])} --layout LAYOUT --episodes {c['episodes']} --seed SEED"
        f"{'' if c['see_through_walls'] else ' --no-see-through-walls'}</code></p>",
        "<h2>Archive</h2>", _img(collection_dir / "heatmap.png"),
        "<h2>Worst levels</h2><div class='grid'>",
    ]
    for lv in levels[:WORST_SHOWN]:
        parts.append(
            f"<div class='card'>{_img(collection_dir / lv['image_file'])}<br>"
            f"#{lv['id']}: {html.escape(c['objective'])} {lv['objective']:.3f}, success {lv['success_rate']:.2f}, "
            f"mean path {lv['mean_path_length']:.1f} (optimal {lv['optimal_path_length']}), {lv['num_walls']} walls, "
            f"seed {lv['seed']}<br><a href='{lv['layout_file']}'>{lv['layout_file']}</a></div>")
    parts.append("</div><h2>Per-region statistics</h2>")
    regions = region_statistics(levels, measures)
    parts.append(_table(
        [*(f"{m} range" for m in measures), "levels", f"mean {c['objective']}", "mean success", "min success",
         "mean path length", "worst level"],
        [[*(f"{lo:.1f} – {hi:.1f}" for lo, hi in r["ranges"].values()), r["levels"], f"{r['objective']:.3f}",
          f"{r['success_rate']:.3f}", f"{r['min_success_rate']:.3f}", f"{r['mean_path_length']:.1f}",
          f"#{r['worst']}"] for r in regions], left=len(measures)))
    parts.append("<h2>All levels</h2>")
    parts.append(_table(
        ["id", "layout", "image", c["objective"], "success", "mean path", "optimal", "walls",
         *measures, "seed", "search objective"],
        [[lv["id"], f"<a href='{lv['layout_file']}'>{lv['layout_file']}</a>", f"<a href='{lv['image_file']}'>png</a>",
          f"{lv['objective']:.3f}", f"{lv['success_rate']:.2f}", f"{lv['mean_path_length']:.1f}",
          lv["optimal_path_length"], lv["num_walls"], *(f"{lv['measures'][m]:.1f}" for m in measures),
          lv["seed"], f"{lv['search_objective']:.3f}"] for lv in levels], left=0))
    path = collection_dir / "report.html"
    atomic_write_text(path, _page(f"Audit of {c['agent']}", "".join(parts)))
    return path


def write_compare_report(path: str | Path, comparison: dict[str, Any], *, collection_dir: str | Path,
                         images: dict[int, bytes]) -> Path:
    """Writes the comparison page; ``images`` maps level id → PNG of agent B's occupancy on it."""
    collection_dir = Path(collection_dir)
    path = Path(path)
    # Links relative to the page, so they work wherever the collection and the page are moved together.
    link = lambda file: html.escape(os.path.relpath(collection_dir / file, path.parent))  # noqa: E731
    a, b = comparison["agent_a"], comparison["agent_b"]
    rows = comparison["levels"]
    summary = comparison["summary"]
    parts = [
        f"<p>A = <code>{html.escape(a)}</code>, B = <code>{html.escape(b)}</code>, on the "
        f"{len(rows)} levels of <code>{html.escape(str(collection_dir))}</code>, each with its recorded seed and "
        f"{comparison['episodes_note']}.</p>",
        _table(["", "A", "B"], [
            ["mean success rate", f"{summary['success_a']:.3f}", f"{summary['success_b']:.3f}"],
            ["mean path length", f"{summary['path_a']:.1f}", f"{summary['path_b']:.1f}"],
            ["levels solved every episode", summary["solved_a"], summary["solved_b"]],
        ], left=1),
        f"<p>B is worse on <b>{summary['b_worse']}</b> levels and better on <b>{summary['b_better']}</b> "
        f"(success-rate difference beyond {summary['threshold']:.2f}).</p>",
        "<h2>Where B is worst relative to A</h2><div class='grid'>",
    ]
    for row in rows:
        if row["id"] in images:
            data = base64.b64encode(images[row["id"]]).decode("ascii")
            parts.append(f"<div class='card'><img src='data:image/png;base64,{data}'><br>#{row['id']}: success "
                         f"A {row['success_a']:.2f} → B {row['success_b']:.2f}; path {row['path_a']:.0f} → "
                         f"{row['path_b']:.0f}</div>")
    parts.append("</div><h2>All levels (B − A)</h2>")
    classes = ["worse" if r["verdict"] == "worse" else "better" if r["verdict"] == "better" else "" for r in rows]
    parts.append(_table(
        ["id", "layout", "success A", "success B", "Δ success", "path A", "path B", "Δ path", "verdict"],
        [[r["id"], f"<a href='{link(r['layout_file'])}'>{r['layout_file']}</a>",
          f"{r['success_a']:.2f}", f"{r['success_b']:.2f}", f"{r['success_b'] - r['success_a']:+.2f}",
          f"{r['path_a']:.1f}", f"{r['path_b']:.1f}", f"{r['path_b'] - r['path_a']:+.1f}", r["verdict"]]
         for r in rows], left=0, row_classes=classes))
    atomic_write_text(path, _page(f"Compare {a} vs {b}", "".join(parts)))
    return path
