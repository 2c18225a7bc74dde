"""The comparison page of two agents on a collection's levels (:mod:`dsage_ray.audit.compare`)."""

from __future__ import annotations

import os
import urllib.parse
from pathlib import Path
from typing import Any

from dsage_ray.audit.report.blocks import (collection_href, esc, html_page, html_table, img_tag, number_format,
                                           scroll_box)
from dsage_ray.io import atomic_write_text


def write_compare_report(path: str | Path, comparison: dict[str, Any], *, collection_dir: str | Path,
                         images: dict[int, bytes]) -> Path:
    """Writes the comparison page (:func:`~dsage_ray.audit.compare.compare_agents`'s result); ``images`` maps
    level id → PNG of agent B's evaluation of it. Beside the success rates, the page shows the compared
    columns of the domain (``comparison["columns"]``: Maze's mean path length, Mario's completion)."""
    collection_dir = Path(collection_dir)
    path = Path(path)

    def link(file: Any) -> str:
        # Relative to the page, so it works wherever the collection and the page are moved together.
        if collection_href(file) is None:
            return esc(file)
        href = urllib.parse.quote(Path(os.path.relpath(collection_dir / file, path.parent)).as_posix())
        return f"<a href='{href}'>{esc(file)}</a>"

    a, b = comparison["agent_a"], comparison["agent_b"]
    rows = comparison["levels"]
    summary = comparison["summary"]
    columns = comparison.get("columns", [])
    number = {c["key"]: number_format([r[f"{c['key']}_{role}"] for r in rows for role in "ab"]) for c in columns}
    title = f"Compare {a} vs {b}"
    parts = [
        f"<h1>{esc(title)}</h1><p class='lead'>A = <code>{esc(a)}</code>, B = <code>{esc(b)}</code>, on the "
        f"{len(rows)} levels of <code>{esc(collection_dir)}</code>, each with its recorded seed and "
        f"{esc(comparison['episodes_note'])}.</p>",
        html_table(["", "A", "B"], [
            ["mean success rate", f"{summary['success_a']:.3f}", f"{summary['success_b']:.3f}"],
            *([esc(c["mean"]), number[c["key"]](summary[f"{c['key']}_a"]), number[c["key"]](summary[f"{c['key']}_b"])]
              for c in columns),
            ["levels solved every episode", summary["solved_a"], summary["solved_b"]],
        ], left=1, table_attrs=""),
        f"<p>B is worse on <b>{summary['b_worse']}</b> levels and better on <b>{summary['b_better']}</b> "
        f"(success-rate difference beyond {summary['threshold']:.2f}).</p>",
        "<h2>Where B is worst relative to A</h2><div class='cards'>",
    ]
    for row in rows:
        if row["id"] in images:
            alt = f"level {row['id']}"
            changes = "".join(f"; {esc(c['label'])} {number[c['key']](row[c['key'] + '_a'])} → "
                              f"{number[c['key']](row[c['key'] + '_b'])}" for c in columns)
            parts.append(f"<div class='card'>{img_tag(images[row['id']], alt=alt)}"
                         f"<div>#{esc(row['id'])}: success A {row['success_a']:.2f} → B {row['success_b']:.2f}"
                         f"{changes}</div></div>")
    parts.append("</div><h2>All levels (B − A)</h2><p class='lead'>Click a column header to sort.</p>")
    classes = [f"class='{r['verdict']}'" if r["verdict"] in ("worse", "better") else "" for r in rows]
    headers = ["id", "level", "success A", "success B", "Δ success",
               *(f"{c['label']} {x}" for c in columns for x in ("A", "B", "Δ")), "verdict"]
    cells = [[esc(r["id"]), link(r["level_file"]),
              f"{r['success_a']:.2f}", f"{r['success_b']:.2f}", f"{r['success_b'] - r['success_a']:+.2f}",
              *(text for c in columns for text in (
                  number[c["key"]](r[c["key"] + "_a"]), number[c["key"]](r[c["key"] + "_b"]),
                  f"{r[c['key'] + '_b'] - r[c['key'] + '_a']:+.3g}")),
              esc(r["verdict"])] for r in rows]
    parts.append(scroll_box(html_table(
        headers, cells, left=0, numeric=[True, False, *([True] * (len(headers) - 3)), False],
        row_attrs=classes, sorted_by=(4, "ascending"))))
    atomic_write_text(path, html_page(title, "".join(parts)))
    return path
