"""``series.html``: one self-contained page for an audit series (:mod:`dsage_ray.audit.series`).

Three parts, in the style of the collection report (:mod:`dsage_ray.audit.report`, whose page, table and
picture blocks it uses):

* a **timeline** (a PNG): the success rate on the regression suite per checkpoint, and per checkpoint the
  levels its search added to the suite, the regressed and the fixed ones;
* a **table per checkpoint**: its label, step, suite success, fixed, regressed, new failures, never-solved
  levels and failure cells of its audit, and a link to its audit's ``report.html``;
* the **level × checkpoint matrix**: one row per suite level, one column per checkpoint, each cell the level's
  success rate at that checkpoint, coloured from red (0) to green (1), blank before the level was found.

Like the collection report, it fits a phone's width: the tables scroll in their own boxes, the matrix keeps
its level column in view.
"""

from __future__ import annotations

import io
import math
import os
from pathlib import Path
from typing import Any, Sequence

from dsage_ray.audit.report.blocks import collection_href, esc, html_page, html_table, img_tag
from dsage_ray.io import atomic_write_text

#: Page file name (also :data:`dsage_ray.audit.series.SERIES_REPORT`).
REPORT_NAME = "series.html"

_STYLE = """<style>
.matrix td, .matrix th { padding: 0; } .matrix th { padding: 3px 6px; }
.matrix td span.c { display: block; padding: 3px 6px; min-width: 2.4rem; text-align: center; }
.matrix td span.c.regressed { box-shadow: inset 0 0 0 2px #b03a2e; font-weight: 700; }
.matrix td span.c.fixed { box-shadow: inset 0 0 0 2px #2e7d32; }
.matrix td span.c.none { background: #f1f2f4; color: #9aa1aa; }
.matrix tr > :first-child { position: sticky; left: 0; background: #fff; z-index: 1; padding: 3px 6px; }
.matrix thead tr > :first-child { z-index: 2; background: var(--head); }
.figs img.timeline { max-width: 600px; }
#summary .stat { min-width: 6.5rem; flex: 1 1 6.5rem; }
.legend span { display: inline-block; padding: 0 .4rem; margin: 0 .1rem; border-radius: 3px; }
td.err { white-space: normal; min-width: 14rem; text-align: left; color: var(--accent); }
td.lbl { white-space: normal; overflow-wrap: anywhere; min-width: 9.5rem; max-width: 16rem; text-align: left; }
</style>"""


def success_colour(rate: float) -> str:
    """The matrix cell's background: red at 0, yellow at 0.5, green at 1 (light, so the number reads)."""
    rate = min(max(float(rate), 0.0), 1.0)
    return f"hsl({round(120 * rate)}, 70%, 80%)"


def timeline_png(records: Sequence[dict[str, Any]]) -> bytes:
    """Suite success per checkpoint (top) and new failures, regressed and fixed levels per checkpoint (bottom)."""
    import numpy as np
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    x = np.arange(len(records))
    success = [np.nan if r.get("suite_success_rate") is None else r["suite_success_rate"] for r in records]
    # Narrow and with large type: on a phone the picture shrinks to about half its width.
    fig = Figure(figsize=(6.0, 6.4), dpi=100)
    FigureCanvasAgg(fig)
    top, bottom = fig.subplots(2, 1, sharex=True, gridspec_kw={"height_ratios": [1, 1]})
    top.plot(x, success, marker="o", color="#1f6feb", linewidth=2)
    top.set_ylim(-0.03, 1.03)
    top.set_ylabel("suite success", fontsize=16)
    top.set_title("Regression suite per checkpoint", fontsize=16)
    top.grid(alpha=0.3)
    failed = [xi for xi, r in zip(x, records) if r.get("error")]
    for xi in failed:
        top.axvspan(xi - 0.4, xi + 0.4, color="#b03a2e", alpha=0.2, linewidth=0,
                    label="audit failed" if xi == failed[0] else None)
    if failed:
        top.legend(fontsize=13, loc="lower left")
    width = 0.27
    for offset, key, colour, name in ((-width, "new_failures", "#6a3d9a", "new failures"),
                                      (0.0, "regressed", "#b03a2e", "regressed"),
                                      (width, "fixed", "#2e7d32", "fixed")):
        values = [r[key] if key == "new_failures" else len(r[key]) for r in records]
        bottom.bar(x + offset, values, width=width, color=colour, label=name)
    bottom.set_ylabel("levels", fontsize=16)
    bottom.legend(fontsize=14, ncol=3, loc="upper center", bbox_to_anchor=(0.5, -0.25), frameon=False,
                  handlelength=1.0, columnspacing=1.0)
    bottom.grid(alpha=0.3, axis="y")
    bottom.yaxis.get_major_locator().set_params(integer=True)
    step = max(1, math.ceil(len(records) / 8))
    bottom.set_xticks(x[::step], [f"#{i}" for i in x[::step]])
    bottom.set_xlabel("checkpoint", fontsize=16)
    for ax in (top, bottom):
        ax.tick_params(labelsize=14)
    fig.tight_layout()
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png")
    return buffer.getvalue()


def _number(value: Any, fmt: str = "{:.3f}") -> str:
    return "" if value is None else fmt.format(value)


def _checkpoint_table(out_dir: Path, records: Sequence[dict[str, Any]]) -> str:
    errors = any(r.get("error") for r in records)
    headers = ["#", "checkpoint", "step", "suite success", "suite levels", "fixed", "regressed", "new failures",
               "never solved", "failure cells", "minutes", "report", *(["error"] if errors else [])]
    rows = []
    for r in records:
        summary = r.get("summary") or {}
        report = None
        if r.get("audit_dir"):
            path = Path(r["audit_dir"]) / "collection" / "report.html"
            # Only a report inside the series folder is linked (series.json may come from someone else).
            if collection_href(path.as_posix()) and (out_dir / path).is_file():
                report = collection_href(path.as_posix())
        row = [
            r["index"],
            f"<span title='{esc(r['agent'])}'>{esc(r['label'])}</span>",
            "" if r.get("step") is None else f"{r['step']:,}",
            _number(r.get("suite_success_rate")),
            r["suite_size"],
            len(r["fixed"]),
            (f"<span class='bad'>{len(r['regressed'])}</span>" if r["regressed"] else "0", len(r["regressed"])),
            r["new_failures"],
            _number(summary.get("never_solved"), "{}"),
            _number(summary.get("failure_cells"), "{}"),
            f"{r['wall_time'] / 60:.1f}",
            f"<a href='{report}'>report</a>" if report else "",
        ]
        if errors:
            row.append(esc(r.get("error") or ""))
        rows.append(row)
    table = html_table(headers, rows, numeric=[True, False, True, True, True, True, True, True, True, True, True, False,
                                           False], sorted_by=(0, "ascending"),
                   titles={"suite success": "mean success rate over the suite levels found by earlier checkpoints",
                           "fixed": "suite levels failing at their previous result, not failing now",
                           "regressed": "suite levels not failing at their previous result, failing now",
                           "new failures": "failing levels of this checkpoint's audit that joined the suite",
                           "never solved": "levels of this checkpoint's audit with success rate 0",
                           "failure cells": "archive cells of this checkpoint's audit with a failing level"})
    # The label and error cells wrap (class set after the fact: the table helper styles columns by position).
    table = table.replace("<td><span title=", "<td class='lbl'><span title=")
    if errors:
        table = _mark_last_column(table, "err")
    return f"<div class='hscroll'>{table}</div>"


def _mark_last_column(table: str, cls: str) -> str:
    rows = table.split("</tr>")
    out = []
    for row in rows:
        at = row.rfind("<td>")
        out.append(row[:at] + f"<td class='{cls}'>" + row[at + 4:] if at >= 0 else row)
    return "</tr>".join(out)


def _matrix(records: Sequence[dict[str, Any]], suite: Sequence[dict[str, Any]]) -> str:
    changes = {(i, r["index"]): kind for r in records for kind in ("fixed", "regressed") for i in r[kind]}
    headers = ["level", "found", *(f"#{r['index']}" for r in records)]
    rows = []
    for level in suite:
        results = {int(k): v for k, v in level["results"].items()}
        href = collection_href(level.get("level_file"))
        link = f"<a href='{href}'>{esc(level['id'])}</a>" if href else esc(level["id"])
        cells: list[Any] = [(link, level["id"]), (f"#{esc(level['origin'])}", level["origin"])]
        for r in records:
            k = r["index"]
            if k < level["origin"]:
                cells.append(("", ""))
            elif k not in results:
                cells.append(("<span class='c none' title='not measured (its audit failed)'>–</span>", ""))
            else:
                kind = changes.get((level["id"], k), "")
                rate = results[k]
                note = f", {kind}" if kind else ""
                cells.append((f"<span class='c {kind}' style='background:{success_colour(rate)}' "
                              f"title='level {esc(level['id'])} at #{k}: success {rate:.2f}{note}'>"
                              f"{rate:.2f}</span>", rate))
        rows.append(cells)
    table = html_table(headers, rows, numeric=[True] * len(headers), table_attrs="class='sortable matrix'",
                   sorted_by=(0, "ascending"),
                   titles={"level": "the level's id in the suite (a link to its level file)",
                           "found": "the checkpoint whose audit found the level",
                           **{f"#{r['index']}": r["label"] for r in records}})
    return f"<div class='scroll'>{table}</div>"


def write_series_report(out_dir: str | os.PathLike[str], series: dict[str, Any]) -> Path:
    """Writes ``out_dir/series.html`` for the series (what ``series.json`` holds); returns its path."""
    out_dir = Path(out_dir)
    records, suite = series["records"], series["suite"]
    latest = next((r for r in reversed(records) if r.get("suite_success_rate") is not None), None)
    failed = sum(1 for r in records if r.get("error"))
    title = f"Audit series: {len(records)} checkpoint{'s' if len(records) != 1 else ''}"
    lead = (f"Each checkpoint is re-evaluated on the regression suite (the failing levels that earlier checkpoints' "
            f"audits found, each with its recorded seed and {esc(series['episodes'])} episodes), then audited "
            f"by a {esc(series['budget'])}-evaluation search (preset {esc(series['preset'])}, domain "
            f"{esc(series['domain'])}{', warm-started from the previous audit' if series.get('warm_start') else ''}"
            f") whose new failing levels join the suite. A level is failing when its {esc(series['failing'])}.")
    tiles = [(len(records), "checkpoints"), (len(suite), "suite levels"),
             (_number(latest and latest["suite_success_rate"]) or "n/a",
              f"suite success, #{latest['index']}" if latest else "suite success"),
             (sum(len(r["regressed"]) for r in records), "regressions"),
             (sum(len(r["fixed"]) for r in records), "fixes")]
    if failed:
        tiles.append((failed, "failed audits"))
    parts = [_STYLE, f"<h1>{esc(title)}</h1><p class='lead'>{lead}</p>",
             "<div class='stats' id='summary'>"
             + "".join(f"<div class='stat'><b>{esc(v)}</b><span>{esc(t)}</span></div>" for v, t in tiles)
             + "</div>"]
    if records:
        timeline = img_tag(timeline_png(records), alt="timeline").replace("<img ", "<img class='timeline' ", 1)
        parts += ["<h2>Timeline</h2>", "<div class='figs'>", timeline, "</div>",
                  "<h2>Checkpoints</h2>",
                  "<p class='lead'>Hover a header for its meaning; <i>report</i> opens the checkpoint's audit.</p>",
                  _checkpoint_table(out_dir, records)]
    legend = ("<p class='lead legend'>Each cell: the level's success rate at that checkpoint "
              f"(<span style='background:{success_colour(0)}'>0</span>"
              f"<span style='background:{success_colour(0.5)}'>0.5</span>"
              f"<span style='background:{success_colour(1)}'>1</span>); "
              "a red frame: regressed there, a green frame: fixed there; blank: not found yet. "
              "Click a header to sort.</p>")
    parts += [f"<h2>Levels × checkpoints ({len(suite)} levels)</h2>", legend,
              _matrix(records, suite) if suite
              else "<p>The suite is empty: no audit has found a failing level yet.</p>"]
    path = out_dir / REPORT_NAME
    atomic_write_text(path, html_page(title, "".join(parts)))
    return path
