"""``report.html``: the self-contained page of a collection.

One file that opens anywhere, with no network: inline CSS, a small inline script (sortable tables, a text
filter, "never solved" and per-measure range filters), base64-embedded heatmaps and worst-level pictures.
The full table links to the collection's own level files and pictures by relative path, which keeps the page
small for a thousand levels and its links working wherever the collection folder is moved.

**Reproduce commands.** The collection records each level's command (``reproduce``) with the absolute path the
audit wrote its level file to, so that it runs from any directory of that machine. The page shows it with the
level file relative to the collection folder instead (:func:`~dsage_ray.audit.report.blocks.portable_command`),
and says to run it there: the command then works wherever the folder is, on any machine.

**A collection from someone else.** Every field put into the page is escaped, every number the page computes
with is checked to be one (:func:`~dsage_ray.audit.report.statistics.check_numbers`: a ``ValueError`` names the
field that is not), and a file named by a field is linked, or its picture embedded, only when the name is a
relative path inside the collection folder (:func:`~dsage_ray.audit.report.blocks.collection_href`): a
``javascript:`` or ``http:`` name, an absolute path or a ``..`` step out is shown as text, not linked.

Nothing here knows a domain: which of an entry's numbers are shown, under which label, in which format and
with which explanation, and which of the collection's settings, is the domain's registration's
(:class:`~dsage_ray.domains.AuditSpec` ``columns`` and ``settings``).
The page fits a phone's width: wide tables scroll inside their own box (a line above says so when they do),
pictures shrink to a card's width, which their text is sized for, commands wrap.
"""

from __future__ import annotations

import math
import os
import shlex
from pathlib import Path
from typing import Any, Callable, Sequence

from dsage_ray.audit.collection_file import audit_declaration, load_collection
from dsage_ray.audit.nominal import record_summary
from dsage_ray.audit.report.blocks import (collection_file, column_decimals, command_block, esc, file_link,
                                           html_page, html_table, img_tag, is_number, number_format,
                                           portable_command, scroll_box)
from dsage_ray.audit.report.heatmaps import heatmap_pngs
from dsage_ray.audit.report.statistics import (FAILURE_RATE, REGIONS_PER_MEASURE, check_numbers, failure_rate,
                                               is_regression, objective_label, printed_range, ranking_name,
                                               reference_numbers, region_statistics, report_columns,
                                               shows_objective)
from dsage_ray.audit.summary import FAILURE_CELL_RATE, failure_summary
from dsage_ray.domains import ReportField
from dsage_ray.io import atomic_write_text

#: Levels shown with their picture at the top of a report.
WORST_SHOWN = 12



def episodes_phrase(count: object) -> str:
    """``1 episode``, ``5 episodes`` (escaped for the page)."""
    return f"{esc(count)} episode{'' if str(count) == '1' else 's'}"

def _reference_command(collection: dict[str, Any], entry: dict[str, Any], command: str) -> str | None:
    """The reference agent's command for ``entry``: recorded, or the agent's with the agent spec swapped."""
    reference = entry.get("reference") or {}
    if reference.get("reproduce"):
        return reference["reproduce"]
    flag = f"--agent {shlex.quote(collection['agent'])}"
    if collection.get("reference") and command.count(flag) == 1:
        return command.replace(flag, f"--agent {shlex.quote(collection['reference'])}")
    return None


def _search_folder(folder: Any, collection_dir: Path) -> str:
    """The search folder a collection names: relative to the collection folder where both lie in one audit
    folder (``../search``, which stays right when the audit folder moves), else as recorded."""
    if not isinstance(folder, str) or not folder:
        return "?"
    audit_dir = collection_dir.resolve().parent
    if Path(folder).is_absolute() and Path(folder).is_relative_to(audit_dir):
        return os.path.relpath(folder, collection_dir.resolve())
    return folder


def _coverage(c: dict[str, Any]) -> str:
    cells = math.prod(int(d) for d in c["archive_dims"])
    elites = c.get("search_elites")
    if not is_number(elites) or cells <= 0:
        return "?"
    return f"{int(elites):,} of {cells:,} archive cells hold an elite ({elites / cells:.2%})"


def _metadata(c: dict[str, Any], collection_dir: Path) -> str:
    config = c.get("config") or {}
    ranges = ", ".join(f"{m} [{lo:g}, {hi:g}] in {d} cells"
                       for m, (lo, hi), d in zip(c["measures"], c["measure_ranges"], c["archive_dims"]))
    items = [
        ("domain", esc(c["domain"])),
        ("agent", f"<code>{esc(c['agent'])}</code>"),
        ("reference", f"<code>{esc(c['reference'])}</code>" if c.get("reference") else "none"),
        *([("nominal check", _nominal(c))] if "nominal" in c else []),
        ("objective", esc(c["objective"])),
        ("measures", esc(ranges)),
        ("preset", esc(config.get("preset", "?"))),
        ("budget", f"{esc(config.get('budget', '?'))} real evaluations in the search"),
        ("episodes", f"{esc(c['episodes'])} per level (re-evaluation)"),
        ("seed", f"{esc(c.get('run_seed', '?'))} (each level's evaluation seed is in the table)"),
        ("search folder", f"<code>{esc(_search_folder(c.get('search_dir'), collection_dir))}</code>"),
        ("coverage", esc(_coverage(c))),
        ("created", esc(c.get("created", "?"))),
    ]
    audit = audit_declaration(c["domain"])
    items += [(esc(setting.name), esc(setting.text(c[setting.key]))) for setting in (audit.settings if audit else ())
              if c.get(setting.key) is not None]
    if c.get("notes"):
        items.append(("notes", esc(c["notes"])))
    return "<dl class='meta'>" + "".join(f"<dt>{k}</dt><dd>{v}</dd>" for k, v in items) + "</dl>"


def _nominal(c: dict[str, Any]) -> str:
    """The header's text of the audit's nominal check (the agent on the domain's nominal level before the search),
    marked where it failed."""
    record = c["nominal"]
    text = esc(record_summary(record)) if isinstance(record, dict) else "?"
    passed = isinstance(record, dict) and record.get("verdict") == "ok"
    return text if passed else f"<span class='bad'>{text}</span>"


def _nominal_failed(c: dict[str, Any]) -> bool:
    record = c.get("nominal")
    return isinstance(record, dict) and record.get("verdict") != "ok"


def _summary(s: dict[str, Any]) -> str:
    cvar = "n/a" if s["cvar10"] is None else f"{s['cvar10']:.3f}"
    tiles = [
        (s["levels"], "levels"),
        (s["with_failures"], "with at least one failure"),
        (s["never_solved"], "never solved"),
        (s["failure_cells"], f"archive cells with failure rate ≥ {FAILURE_CELL_RATE:g}"),
        (cvar, "mean success rate of the worst 10% (CVaR)"),
    ]
    if "regressed" in s:
        top = s["mean_regression_top10"]
        tiles += [(s["regressed"], "levels where the agent does worse than the reference"),
                  ("n/a" if top is None else f"{top:+.3f}", "mean regression of the worst 10%")]
    return ("<div class='stats' id='summary'>"
            + "".join(f"<div class='stat'><b>{esc(v)}</b><span>{esc(label)}</span></div>" for v, label in tiles)
            + "</div>")


def _card(c: dict[str, Any], lv: dict[str, Any], collection_dir: Path, columns: Sequence[ReportField],
          formats: dict[str, Callable[[Any], str]], notes: dict[str, str]) -> str:
    """One worst-level card: picture(s), the level's numbers (next to the reference's), its command(s)."""
    reference = lv.get("reference") if is_regression(c) else None
    pictures = [(c["agent"], lv["image_file"])]
    if reference and reference.get("image_file"):
        pictures.append((c["reference"], reference["image_file"]))

    def figure(name: str, file: Any) -> str:
        path = collection_file(collection_dir, file)
        picture = img_tag(path.read_bytes(), alt=path.name) if path else "(no picture)"
        caption = f"<figcaption>{esc(name)}</figcaption>" if len(pictures) > 1 else ""
        return f"<figure>{picture}{caption}</figure>"

    cell = lambda key, v: "" if v is None else formats.get(key, number_format([v]))(v)  # noqa: E731
    label = lambda name, key: (f"<td class='l' title='{esc(notes[key])}'>{esc(name)}</td>"  # noqa: E731
                               if key in notes else f"<td class='l'>{esc(name)}</td>")
    rows = _card_rows(c, lv, reference, columns)
    if reference:
        body = "".join(f"<tr>{label(name, key)}<td>{cell(key, v)}</td><td>{cell(key, ref)}</td></tr>"
                       for name, key, v, ref in rows)
        # Role names keep the card narrow; the specs are in the page header and the tooltips.
        head = (f"<tr><th class='l'></th><th title='{esc(c['agent'])}'>agent</th>"
                f"<th title='{esc(c['reference'])}'>reference</th></tr>")
        mark = " class='bad'" if lv["regression"] > 0 else ""
        headline = f"#{lv['id']}: <span{mark}>regression {lv['regression']:+.2f}</span>"
    else:
        body = "".join(f"<tr>{label(name, key)}<td>{cell(key, v)}</td></tr>" for name, key, v, _ in rows)
        head = ""
        key, value = ("objective", lv["objective"]) if shows_objective(c) else ("failure_rate", failure_rate(lv))
        headline = f"#{lv['id']}: {esc(ranking_name(c))} {cell(key, value)}"
    command = portable_command(lv["reproduce"], lv["level_file"])
    parts = [f"<div class='card'><h3>{headline}</h3><div class='pics'>"
             + "".join(figure(name, file) for name, file in pictures) + "</div>",
             f"<table>{head}{body}</table>", f"<div>seed {esc(lv['seed'])}, {episodes_phrase(lv['episodes'])}:</div>",
             command_block(command)]
    reference_command = _reference_command(c, lv, command) if reference else None
    if reference_command:
        parts += ["<div>the reference, same seed:</div>",
                  command_block(portable_command(reference_command, lv["level_file"]))]
    return "".join(parts) + "</div>"


def _card_rows(c: dict[str, Any], lv: dict[str, Any], reference: dict[str, Any] | None,
               columns: Sequence[ReportField]) -> list[tuple[str, str, Any, Any]]:
    """A card's table: ``(label, format key, the level's value, the reference's)`` per row. The failure rate is
    a row only where the headline shows another number (a regression, an objective of its own)."""
    ref = reference or {}
    rows = []
    if reference or shows_objective(c):
        rows.append((FAILURE_RATE, "failure_rate", failure_rate(lv), failure_rate(ref) if ref else None))
    rows += [(m, m, v, None) for m, v in lv["measures"].items()]
    rows += [(column.name, column.key, lv[column.key], ref.get(column.key)) for column in columns]
    rows += [(k.replace("_", " "), k, None, ref[k]) for k in (reference_numbers(c) if ref else ())
             if k not in lv and k != "success_rate"]
    return rows


def _levels_table(c: dict[str, Any], columns_shown: Sequence[ReportField], formats: dict[str, Callable[[Any], str]],
                  notes: dict[str, str]) -> str:
    levels, measures = c["levels"], c["measures"]
    objective = objective_label(c)
    columns: list[tuple[str, str, Callable[[dict[str, Any]], Any]]] = [("id", "id", lambda lv: lv["id"])]
    if shows_objective(c):
        columns.append((objective, "objective", lambda lv: lv["objective"]))
    columns.append((FAILURE_RATE, "failure_rate", failure_rate))
    if is_regression(c):
        columns.append((f"reference {FAILURE_RATE}", "failure_rate", lambda lv: failure_rate(lv["reference"])))
        columns += [(f"reference {k.replace('_', ' ')}", k, lambda lv, k=k: lv["reference"].get(k))
                    for k in reference_numbers(c) if k != "success_rate"]
        columns.append(("regression", "regression", lambda lv: lv.get("regression")))
    columns += [(m, m, lambda lv, m=m: lv["measures"][m]) for m in measures]
    columns += [(column.name, column.key, lambda lv, k=column.key: lv[k]) for column in columns_shown]
    columns += [("seed", "seed", lambda lv: lv["seed"]),
                ("search objective", "search_objective", lambda lv: lv.get("search_objective"))]
    # The domain's columns as on the cards (their declared format, if any); the others suited to their values.
    column_formats = [formats.get(key) or number_format([get(lv) for lv in levels]) for _, key, get in columns]
    rows, attrs = [], []
    for lv in levels:
        cells = [f(get(lv)) for (_, _, get), f in zip(columns, column_formats)]
        command = portable_command(lv["reproduce"], lv["level_file"])
        # Paths relative to the collection folder, which wrap; the command is the copy button's.
        cells.append(f"{file_link(lv['level_file'], lv['level_file'])} {file_link(lv['image_file'], 'picture')} "
                     f"<button class='copy' type='button' data-cmd='{esc(command)}' "
                     f"title='copy the command: {esc(command)}'>copy</button>")
        rows.append(cells)
        regression = f" data-r='{lv['regression']!r}'" if "regression" in lv else ""
        # The row's id is the target of the region table's "worst level" links.
        attrs.append(f"id='level-{lv['id']}' data-s='{lv['success_rate']!r}' "
                     f"data-m='{' '.join(repr(float(lv['measures'][m])) for m in measures)}'{regression}")
    headers = [name for name, _, _ in columns] + ["files"]
    numeric = [True] * len(columns) + [False]
    return scroll_box(html_table(
        headers, rows, left=0, numeric=numeric, row_attrs=attrs, table_attrs="class='sortable' id='levels'",
        sorted_by=(0, "ascending"), cell_classes={len(columns): "files"},
        titles={"search objective": "the search's own value when it kept the level (one evaluation, another seed)",
                **{f.name: notes[f.key] for f in columns_shown if f.key in notes}},
        descending_first={objective, FAILURE_RATE, f"reference {FAILURE_RATE}", "regression", "search objective"}),
        box="scroll")


def _filters(c: dict[str, Any]) -> str:
    parts = ["<div class='filters'>",
             "<input type='search' id='query' placeholder='filter: id, file name or number' aria-label='filter'>",
             "<label><input type='checkbox' id='never'> never solved only</label>"]
    if c.get("reference"):
        parts.append("<label><input type='checkbox' id='regressed'> regressed only</label>")
    for j, m in enumerate(c["measures"]):
        values = [lv["measures"][m] for lv in c["levels"]] or [0.0]
        parts.append(f"<label>{esc(m)} <input type='number' step='any' class='lo' data-j='{j}' "
                     f"placeholder='{min(values):g}' aria-label='{esc(m)} from'> to "
                     f"<input type='number' step='any' class='hi' data-j='{j}' placeholder='{max(values):g}' "
                     f"aria-label='{esc(m)} to'></label>")
    parts.append("<button type='button' id='reset'>reset</button> <span id='shown'></span></div>")
    return "".join(parts)


def _regions(c: dict[str, Any], columns: Sequence[ReportField], formats: dict[str, Callable[[Any], str]],
             notes: dict[str, str]) -> str:
    measures, levels = c["measures"], c["levels"]
    averaged = [column for column in columns if column.mean]
    regression = is_regression(c)
    regions = region_statistics(levels, measures, means=[column.key for column in averaged]
                                + (["regression"] if regression else []))
    # Counts and buttons first: on a phone they are what shows without scrolling.
    ranking = f"mean {ranking_name(c)}"
    headers = ["levels", "", ranking, *([f"mean {FAILURE_RATE}"] if ranking != f"mean {FAILURE_RATE}" else []),
               "worst level", *measures, *(column.mean for column in averaged)]
    values = {m: [float(lv["measures"][m]) for lv in levels] for m in measures}
    decimals = {m: column_decimals(values[m]) for m in measures}
    rows = []
    for r in regions:
        printed = {m: printed_range(*r["extent"][m], values[m], decimals[m]) for m in measures}
        lo = " ".join(a for a, _ in printed.values())
        hi = " ".join(b for _, b in printed.values())
        mean = r["regression"] if regression else r["objective"] if shows_objective(c) else 1 - r["success_rate"]
        rows.append([r["levels"],
                     f"<button type='button' class='region' data-lo='{lo}' data-hi='{hi}'>show</button>",
                     f"{mean:+.3f}" if regression else f"{mean:.3f}",
                     *([f"{1 - r['success_rate']:.3f}"] if ranking != f"mean {FAILURE_RATE}" else []),
                     (f"<a href='#level-{r['worst']}'>#{r['worst']}</a>", r["worst"]),
                     *((a if a == b else f"{a} – {b}", float(a)) for a, b in printed.values()),
                     *(formats[column.key](r[column.key]) for column in averaged)])
    numeric = [True, False] + [True] * (len(headers) - 2)
    table = html_table(headers, rows, left=0, numeric=numeric, sorted_by=(2, "descending"),
                   descending_first={ranking, f"mean {FAILURE_RATE}"},
                   titles={**{m: f"the lowest and highest {m} among the region's levels (the regions split each "
                                 f"measure's range into {REGIONS_PER_MEASURE} equal parts)" for m in measures},
                           "worst level": "the region's worst level: opens its row in the table of all levels",
                           **{column.mean: notes[column.key] for column in averaged if column.key in notes}})
    return scroll_box(table)


def _glossary(c: dict[str, Any]) -> str:
    """One line per term the page uses, and how the worst levels are ordered."""
    objective, episodes = objective_label(c), episodes_phrase(c["episodes"])
    cells = " × ".join(str(int(d)) for d in c["archive_dims"])
    terms = [(FAILURE_RATE, f"the share of a level's {episodes} that the agent failed (1 − success rate), "
                            "measured again after the search with the level's recorded seed.")]
    if shows_objective(c):
        terms.append((objective, "the audit's objective, which the search maximised to find these levels; "
                                 "measured again like the failure rate."))
    if is_regression(c):
        terms.append(("regression", "the reference's success rate minus the agent's, on the same seed: above 0, "
                                    "the agent fails more often than the reference."))
    terms += [
        ("search objective", f"the {esc(objective)} the search recorded when it kept the level: one evaluation "
                             "with another seed. The search keeps the highest values it saw, often lucky ones, so "
                             "this is often higher than the number measured again."),
        ("measures", f"numbers that describe a level ({esc(', '.join(c['measures']))}); the search looks for "
                     "failures spread over their values."),
        ("archive cell", f"one cell of the grid that splits each measure's range into equal parts ({cells} "
                         "cells); the search keeps one level per cell."),
        ("elite", "the level an archive cell keeps: the one with the highest search objective found for that "
                  "cell. Every level on this page is an elite, measured again."),
        ("coverage", "the share of the archive's cells that hold an elite."),
        ("CVaR", "conditional value at risk: the mean success rate of the worst 10% of the levels (those with "
                 "the lowest success rates); 0 means the agent never succeeds on them."),
        ("ties", _ties(c)),
    ]
    return ("<dl class='glossary' id='terms'>"
            + "".join(f"<div><dt>{esc(term)}</dt> <dd>{text}</dd></div>" for term, text in terms) + "</dl>")


def _ties(c: dict[str, Any]) -> str:
    """How levels with the same worst-first number are ordered (the collection's order, :func:`~dsage_ray.audit.
    collection.build_collection`): by success rate, then as the search rated them."""
    ranking = ranking_name(c)
    success = "" if ranking == FAILURE_RATE else "with the lower success rate first, then "
    return (f"levels with the same {esc(ranking)} are listed {success}with the higher search objective first, "
            "then in the search archive's order. Numbers are rounded on the page: levels that look tied may "
            "differ in a later decimal.")


def _notes(c: dict[str, Any], columns: Sequence[ReportField]) -> dict[str, str]:
    """Explanations of the domain's numbers, by key (tooltips of their headers and labels): the columns' own,
    with the collection's settings filled in (Maze: its step limit, which a failed episode counts)."""
    return {column.key: text for column in columns if (text := column.explain(c))}


def write_report(collection_dir: str | Path) -> Path:
    """Writes ``report.html`` for the collection in ``collection_dir``; returns its path.

    Raises:
        ValueError: Not a collection, or one whose numbers are not numbers (:func:`check_numbers`).
    """
    collection_dir = Path(collection_dir)
    c = load_collection(collection_dir)
    check_numbers(c)
    levels = c["levels"]
    columns = report_columns(c)
    notes = _notes(c, columns)
    summary = failure_summary(c)
    if c.get("reference"):
        title = f"Regression audit of {c['agent']} against {c['reference']}"
        lead = (f"Levels where <code>{esc(c['agent'])}</code> does worse than <code>{esc(c['reference'])}</code>, "
                f"both evaluated with the same seeds; largest regression first.")
    else:
        title = f"Audit of {c['agent']}"
        lead = f"Levels where <code>{esc(c['agent'])}</code> fails, worst first."
    if _nominal_failed(c):
        lead += (" <span class='bad'>The agent failed its nominal check (see Run below): the failures here may be "
                 "artefacts of how it was played.</span>")
    lead += (f" Every number was measured again after the search with the level's recorded seed and "
             f"{episodes_phrase(c['episodes'])}; each level's command prints it again. The terms are explained "
             f"<a href='#terms'>below</a>.")
    parts = [f"<h1>{esc(title)}</h1><p class='lead'>{lead}</p>", "<h2>Failure diversity</h2>", _summary(summary),
             "<h2>Run</h2>", _metadata(c, collection_dir), "<h2>Terms</h2>", _glossary(c)]
    heatmaps = heatmap_pngs(c)
    if heatmaps:
        parts += ["<h2>Where the levels are</h2>",
                  f"<p class='lead'>Each archive cell's colour is the highest {esc(objective_label(c))} among its "
                  "levels; grey cells hold none.</p><div class='figs'>",
                  img_tag(heatmaps["zoomed"], alt="heatmap, zoomed"),
                  img_tag(heatmaps["full"], alt="heatmap, full range"),
                  "</div>"]
    shown = levels[:WORST_SHOWN]
    # One number format per key across the collection, so the cards line up with each other and the table.
    references = [lv.get("reference") or {} for lv in levels]
    formats = {key: number_format([lv.get(key) for lv in levels] + [r.get(key) for r in references])
               for key in ["objective", *(column.key for column in columns), *reference_numbers(c)]}
    formats["failure_rate"] = number_format([failure_rate(lv) for lv in levels]
                                         + [failure_rate(r) for r in references if is_number(r.get("success_rate"))])
    formats.update({column.key: lambda v, column=column: esc(column.text(v)) for column in columns if column.format})
    formats.update({m: number_format([lv["measures"][m] for lv in levels]) for m in c["measures"]})
    # Two pictures per card (the reference's too) need wider cards.
    wide = " wide" if any((lv.get("reference") or {}).get("image_file") for lv in shown) else ""
    # Where a number needs a sentence (Maze's 648 = a failed episode's step limit), it comes before the cards
    # and tables that show it, and again as their headers' tooltips.
    explained = "".join(f"<p class='lead note'><b>{esc(column.name)}</b>: {esc(notes[column.key])}.</p>"
                        for column in columns if column.key in notes)
    parts += [f"<h2>Worst {len(shown)} levels</h2>", explained,
              "<p class='lead'>Run a level's command in the collection folder (the folder that holds this page: "
              "<code>cd</code> into it first): it names the level file relative to that folder, so it works "
              "wherever the folder is.</p>",
              f"<div class='cards{wide}'>",
              *(_card(c, lv, collection_dir, columns, formats, notes) for lv in shown), "</div>",
              "<h2>Per-region statistics</h2>",
              f"<p class='lead'>Levels grouped by equal-width ranges of each measure; each range printed is the "
              f"lowest and highest value among the region's levels. <i>show</i> filters the table below to the "
              f"region's levels (and clears its other filters); the worst level's link opens its row.</p>",
              _regions(c, columns, formats, notes),
              f"<h2>All {len(levels)} levels</h2>",
              "<p class='lead'>Click a column header (or Tab to it and press Enter) to sort, worst first; "
              "<i>copy</i> copies the level's command, to run in the collection folder.</p>",
              _filters(c), _levels_table(c, columns, formats, notes)]
    path = collection_dir / "report.html"
    atomic_write_text(path, html_page(title, "".join(parts)))
    return path
