"""Self-contained HTML pages for a collection (``report.html``) and an agent comparison.

One file that opens anywhere, with no network: inline CSS, a small inline script (sortable tables, a text
filter, "never solved" and per-measure range filters), base64-embedded heatmaps and worst-level pictures.
The full table links to the collection's own level files and pictures by relative path, which keeps the page
small for a thousand levels and its links working wherever the collection folder is moved.

**Reproduce commands.** The collection records each level's command (``reproduce``) with the absolute path the
audit wrote its level file to, so that it runs from any directory of that machine. The page shows it with the
level file relative to the collection folder instead (:func:`portable_command`), and says to run it there: the
command then works wherever the folder is, on any machine.

**A collection from someone else.** Every field put into the page is escaped, every number the page computes
with is checked to be one (a ``ValueError`` names the field that is not), and a file named by a field is
linked, or its picture embedded, only when the name is a relative path inside the collection folder
(:func:`collection_href`): a ``javascript:`` or ``http:`` name, an absolute path or a ``..`` step out is
shown as text, not linked.

Reads both collection formats through :func:`~dsage_ray.audit.collection_file.load_collection`, which gives a
v1 collection (Maze only) the v2 keys (``domain``, ``reference``, each level's ``reproduce``): only v2 here.
Nothing here knows a domain: which of an entry's numbers are shown, under which label, in which format and
with which explanation, and which of the collection's settings, is the domain's registration's
(:class:`~dsage_ray.domains.AuditSpec` ``columns`` and ``settings``); a collection of a domain that is not
installed shows every numeric key of its entries.
The page fits a phone's width: wide tables scroll inside their own box (a line above says so when they do),
pictures shrink to a card's width, which their text is sized for, commands wrap.
"""

from __future__ import annotations

import base64
import html
import io
import math
import os
import re
import shlex
import urllib.parse
from decimal import ROUND_CEILING, ROUND_FLOOR, Decimal
from pathlib import Path, PurePosixPath
from typing import Any, Callable, Collection, Sequence

import numpy as np

from dsage_ray.audit.collection_file import audit_declaration, load_collection
from dsage_ray.audit.nominal import record_summary
from dsage_ray.audit.summary import FAILURE_CELL_RATE, failure_summary, grid_indices
from dsage_ray.domains import ReportField
from dsage_ray.io import atomic_write_text
from dsage_ray.qd.archives import zoom_window

#: Levels shown with their picture at the top of a report.
WORST_SHOWN = 12
#: Regions per measure in the per-region statistics.
REGIONS_PER_MEASURE = 4
#: Entry keys every domain has; other numeric top-level keys are the domain's own numbers.
_GENERIC_KEYS = {"id", "objective", "success_rate", "seed", "episodes", "search_objective", "regression"}

#: The narrowest the page shows a picture: a worst-level card on a 390 px phone. The pictures' text is sized
#: for it (the domains' ``render`` modules): about 13 px or more there, larger wherever a card is wider.
PICTURE_MIN_WIDTH = 330

_STYLE = """
:root { --line: #d8dbe0; --head: #eef1f5; --muted: #5b6470; --accent: #b03a2e; }
body { font: 15px/1.45 system-ui, -apple-system, "Segoe UI", sans-serif; margin: 0 auto;
       padding: 1.5rem clamp(.75rem, 3vw, 2rem); max-width: 1600px; color: #1d232a; }
img { max-width: 100%; height: auto; }
h1 { font-size: 1.6rem; margin: 0 0 .3rem; } h2 { font-size: 1.25rem; margin: 2rem 0 .6rem; }
p.lead { color: var(--muted); margin-top: 0; }
code { font: 0.86em/1.3 ui-monospace, "DejaVu Sans Mono", monospace; background: #f3f4f6; padding: 1px 4px;
       border-radius: 3px; overflow-wrap: anywhere; }
code.cmd { user-select: all; } code.cmd span { display: inline-block; max-width: 100%; overflow-wrap: anywhere; }
dl.meta { display: grid; grid-template-columns: max-content minmax(0, 1fr); gap: .2rem 1.2rem; margin: 0; }
dl.meta dt { color: var(--muted); } dl.meta dd { margin: 0; overflow-wrap: anywhere; }
dl.glossary { max-width: 62rem; margin: 0; } dl.glossary div { margin: 0 0 .3rem; }
dl.glossary dt { display: inline; font-weight: 600; } dl.glossary dd { display: inline; margin: 0; }
dl.glossary dt::after { content: ":"; }
.stats { display: flex; flex-wrap: wrap; gap: .8rem; }
.stat { border: 1px solid var(--line); border-radius: 6px; padding: .5rem .9rem; min-width: 9rem; }
.stat b { display: block; font-size: 1.6rem; } .stat span { color: var(--muted); font-size: .85rem; }
.figs { display: grid; grid-template-columns: repeat(auto-fit, minmax(min(420px, 100%), 1fr)); gap: 1rem; }
.figs img { width: 100%; max-width: 620px; }
.cards { display: grid; grid-template-columns: repeat(auto-fill, minmax(min(330px, 100%), 1fr)); gap: 1rem; }
.cards.wide { grid-template-columns: repeat(auto-fill, minmax(min(640px, 100%), 1fr)); }
.card { border: 1px solid var(--line); border-radius: 6px; padding: .7rem; display: flex; flex-direction: column;
        gap: .4rem; font-size: .9rem; min-width: 0; }
.card img { width: 100%; max-width: 520px; height: auto; }
.card .pics { display: flex; flex-wrap: wrap; gap: .5rem; }
.card .pics figure { flex: 1 1 300px; min-width: 0; margin: 0; }
.card figcaption { text-align: center; color: var(--muted); }
.card h3 { margin: 0; font-size: 1.05rem; }
.card table { margin: 0; font-size: .85rem; width: 100%; } .card td, .card th { padding: 1px 6px; }
button { font: inherit; font-size: .8rem; padding: 1px 8px; cursor: pointer; }
#levels td button.copy { font-size: .75rem; padding: 0 6px; line-height: 1.25; }
table { border-collapse: collapse; margin: .5rem 0; font-size: .88rem; }
th, td { border: 1px solid var(--line); padding: 3px 8px; text-align: right; white-space: nowrap; }
th { background: var(--head); white-space: normal; vertical-align: bottom; } td.l, th.l { text-align: left; }
td.files { white-space: normal; text-align: left; min-width: 16rem; }
tbody tr:nth-child(even) { background: #fafbfc; } tbody tr:hover { background: #fff6d6; }
table.sortable th { user-select: none; position: sticky; top: 0; z-index: 1; }
th button.sort { font: inherit; color: inherit; background: none; border: 0; padding: 0; cursor: pointer;
                 text-align: inherit; }
th button.sort:focus-visible { outline: 2px solid #1f6feb; outline-offset: 2px; }
table.sortable th[aria-sort=ascending]::after { content: " \\25B2"; }
table.sortable th[aria-sort=descending]::after { content: " \\25BC"; }
.scroll { max-height: 80vh; overflow: auto; border: 1px solid var(--line); }
.hscroll { overflow-x: auto; } .hscroll table { margin: 0; } .scroll table { margin: 0; }
.scrollhint { color: var(--muted); font-size: .85rem; margin: .3rem 0; }
#levels tbody td:first-child { position: sticky; left: 0; background: #fff; }
#levels thead th:first-child { left: 0; z-index: 2; }
#levels tr { scroll-margin-top: 2.5rem; } #levels tr:target { outline: 2px solid #e0a800; outline-offset: -2px; }
.filters { display: flex; flex-wrap: wrap; gap: .6rem 1.4rem; align-items: center; margin: .4rem 0 .6rem; }
.filters input[type=number] { width: 5.5rem; } .filters input[type=search] { width: 16rem; max-width: 100%; }
.worse { background: #fde0dc !important; } .better { background: #e0f5e0 !important; }
.bad { color: var(--accent); font-weight: 600; }
"""

# Sorting for every table.sortable (its headers are buttons, so the keyboard reaches them; a cell's data-sort,
# where it has one, is its sort key); the scroll hints; filters for the table with id "levels" when the page
# has one.
_SCRIPT = """
(function () {
  document.querySelectorAll('table.sortable').forEach(function (table) {
    var body = table.tBodies[0];
    table.tHead.addEventListener('click', function (event) {
      var button = event.target.closest('button.sort');
      if (!button) return;
      var th = button.closest('th'), col = th.cellIndex, numeric = th.classList.contains('num');
      // The first click sorts worst first: largest first where a larger value is worse (data-first).
      var first = th.dataset.first === 'descending' ? -1 : 1;
      var dir = th.getAttribute('aria-sort') === (first === 1 ? 'ascending' : 'descending') ? -first : first;
      table.tHead.querySelectorAll('th').forEach(function (h) { h.removeAttribute('aria-sort'); });
      th.setAttribute('aria-sort', dir === 1 ? 'ascending' : 'descending');
      var keyed = Array.from(body.rows, function (row) {
        var cell = row.cells[col], text = (cell.dataset.sort || cell.textContent).trim(), value = parseFloat(text);
        return [numeric ? (isNaN(value) ? -Infinity : value) : text.toLowerCase(), row];
      });
      keyed.sort(function (a, b) { return a[0] < b[0] ? -dir : a[0] > b[0] ? dir : 0; });
      body.append.apply(body, keyed.map(function (k) { return k[1]; }));
    });
  });
  // A scroll hint shows while the box after it is wider than the screen lets it be.
  function hints() {
    document.querySelectorAll('.scrollhint').forEach(function (hint) {
      var box = hint.nextElementSibling;
      hint.hidden = box.scrollWidth <= box.clientWidth + 1;
    });
  }
  window.addEventListener('resize', hints);
  hints();
  // Copy buttons: the button's own command (data-cmd), or the command beside it.
  document.addEventListener('click', function (event) {
    var button = event.target.closest('button.copy');
    if (!button) return;
    var code = button.previousElementSibling, text = button.dataset.cmd || code.textContent;
    var done = function () { button.textContent = 'copied'; };
    var fallback = function () {
      var area = document.createElement('textarea');
      area.value = text;
      document.body.appendChild(area);
      area.select();
      if (document.execCommand('copy')) done();
      area.remove();
    };
    if (navigator.clipboard) navigator.clipboard.writeText(text).then(done, fallback);
    else fallback();
  });
  var table = document.getElementById('levels');
  if (!table) return;
  var rows = Array.from(table.tBodies[0].rows), query = document.getElementById('query');
  // The text filter reads what a row shows (not its buttons) and its files' names.
  var texts = rows.map(function (row) {
    return Array.from(row.cells, function (cell) {
      return Array.from(cell.childNodes).filter(function (node) { return node.nodeName !== 'BUTTON'; })
        .map(function (node) { return node.textContent; }).join(' ') + ' ' +
        Array.from(cell.querySelectorAll('a'), function (a) { return a.getAttribute('href'); }).join(' ');
    }).join(' ').toLowerCase();
  });
  var never = document.getElementById('never'), regressed = document.getElementById('regressed');
  var lows = Array.from(document.querySelectorAll('input.lo'));
  var highs = Array.from(document.querySelectorAll('input.hi'));
  var shown = document.getElementById('shown');
  function values(inputs) { return inputs.map(function (i) { return parseFloat(i.value); }); }
  function apply() {
    var q = query.value.trim().toLowerCase(), count = 0, lo = values(lows), hi = values(highs);
    rows.forEach(function (row, r) {
      var m = row.dataset.m.split(' ').map(Number);
      var ok = (!q || texts[r].indexOf(q) >= 0) &&
               (!never.checked || Number(row.dataset.s) === 0) &&
               (!regressed || !regressed.checked || Number(row.dataset.r) > 0) &&
               m.every(function (v, j) { return !(v < lo[j]) && !(v > hi[j]); });
      row.hidden = !ok;
      if (ok) count++;
    });
    shown.textContent = count + ' of ' + rows.length + ' levels shown';
  }
  document.querySelectorAll('.filters input').forEach(function (input) { input.addEventListener('input', apply); });
  function clear() {
    document.querySelectorAll('.filters input').forEach(function (i) {
      if (i.type === 'checkbox') i.checked = false; else i.value = '';
    });
  }
  document.getElementById('reset').addEventListener('click', function () { clear(); apply(); });
  // A link to a level's row ("worst level") shows the row even when the filters hide it.
  document.addEventListener('click', function (event) {
    var link = event.target.closest('a[href^="#level-"]');
    var row = link && document.getElementById(link.getAttribute('href').slice(1));
    if (row && row.hidden) { clear(); apply(); }
  });
  // A region's button shows its levels alone: the other filters are cleared, and the range inputs take the
  // range the region table prints.
  document.querySelectorAll('button.region').forEach(function (button) {
    button.addEventListener('click', function () {
      var lo = button.dataset.lo.split(' '), hi = button.dataset.hi.split(' ');
      clear();
      lows.forEach(function (i, j) { i.value = lo[j]; });
      highs.forEach(function (i, j) { i.value = hi[j]; });
      apply();
      table.scrollIntoView();
    });
  });
  apply();
})();
"""


def _esc(value: Any) -> str:
    return html.escape(str(value), quote=True)


#: A URL scheme at the start of a name (``javascript:``, ``http:``, ``data:``, a Windows drive ``C:``).
_SCHEME = re.compile(r"^[A-Za-z][A-Za-z0-9+.\-]*:")


def collection_href(name: Any) -> str | None:
    """The link to a file of the collection that a collection field names, relative to the collection folder.

    A collection may come from someone else, so a field is linked only when it is a relative path that stays
    inside the folder; its characters are percent-encoded, so the browser reads it as a file name and nothing
    else.

    Returns:
        The URL, or None for anything else: an empty or non-text field, a URL scheme (``javascript:``,
        ``http:``), an absolute path, a ``..`` step or a backslash.
    """
    if not isinstance(name, str) or not name or "\\" in name or _SCHEME.match(name):
        return None
    path = PurePosixPath(name)
    if path.is_absolute() or ".." in path.parts:
        return None
    return urllib.parse.quote(path.as_posix())


def _collection_file(collection_dir: Path, name: Any) -> Path | None:
    """The collection's own file that a field names (:func:`collection_href`'s rule, and no symbolic link out
    of the folder), or None: the page embeds no other file of the disk."""
    if collection_href(name) is None:
        return None
    root = collection_dir.resolve()
    path = (root / name).resolve()
    return path if path.is_relative_to(root) and path.is_file() else None


def _file_link(name: Any, text: str) -> str:
    """``text`` linked to the collection's file ``name``; plain text (the name) where it is not one."""
    href = collection_href(name)
    if href is None:
        return f"<span title='not linked: not a file inside the collection folder'>{_esc(name)}</span>"
    return f"<a href='{href}'>{_esc(text)}</a>"


def portable_command(command: str, level_file: str) -> str:
    """``command`` with its level file named relative to the collection folder, to run in that folder.

    The collection records the absolute path of the level file, which is wrong once the folder moves or is
    sent to another machine; the path relative to the folder is right wherever it is. Every absolute path in
    the command that ends with ``level_file`` becomes ``level_file``; the rest is left as it is.
    """
    if collection_href(level_file) is None:
        return command
    try:
        words = shlex.split(command)
    except ValueError:  # not a shell command: shown as it is
        return command
    tail = PurePosixPath(level_file).parts

    def relative(word: str) -> str:
        path = PurePosixPath(word)
        return level_file if path.is_absolute() and path.parts[-len(tail):] == tail else word

    return shlex.join(relative(word) for word in words)


def _compact_png(data: bytes) -> bytes:
    """``data`` re-encoded with a 256-colour palette when that is smaller: figures of flat colours and one
    colour bar lose nothing visible and shrink about threefold, which is what keeps the page light."""
    from PIL import Image

    buffer = io.BytesIO()
    Image.open(io.BytesIO(data)).convert("RGB").quantize(colors=256, method=Image.Quantize.MEDIANCUT).save(
        buffer, format="PNG", optimize=True)
    return min(data, buffer.getvalue(), key=len)


def _img(data: bytes, *, alt: str) -> str:
    encoded = base64.b64encode(_compact_png(data)).decode("ascii")
    return f"<img src='data:image/png;base64,{encoded}' alt='{_esc(alt)}'>"


def _is_number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


def _decimals(values: Sequence[Any]) -> int:
    """Decimals of a column: none for integers, else suited to the column's magnitude."""
    numbers = [float(v) for v in values if _is_number(v)]
    if all(v.is_integer() for v in numbers):
        return 0
    top = max(abs(v) for v in numbers)
    return 3 if top < 10 else 2 if top < 100 else 1


def _formatter(values: Sequence[Any]) -> Callable[[Any], str]:
    """One number format per column (:func:`_decimals`); HTML, so a value that is not a number is escaped."""
    decimals = _decimals(values)

    def text(value: Any) -> str:
        if value is None:
            return ""
        return f"{float(value):.{decimals}f}" if _is_number(value) else _esc(value)

    return text


def _header(text: str) -> str:
    """A header's HTML: may wrap after an underscore, so "optimal_path_length" needs no wide column."""
    return _esc(text).replace("_", "_<wbr>")


def _table(headers: Sequence[str], rows: Sequence[Sequence[Any]], *, left: int = 0, numeric: Sequence[bool] = (),
           row_attrs: Sequence[str] | None = None, table_attrs: str = "class='sortable'",
           sorted_by: tuple[int, str] | None = None, titles: dict[str, str] | None = None,
           descending_first: Collection[str] = (), cell_classes: dict[int, str] | None = None) -> str:
    """A table with a ``thead``; cells are HTML, headers plain text.

    Args:
        headers: Column names; in a sortable table each non-empty one is a button that sorts by its column.
        rows: Cells: HTML, or ``(html, sort_key)`` for a cell that sorts by another value than its text.
        left: Left-aligned leading columns.
        numeric: Per column, whether it sorts as numbers.
        row_attrs: Per row, attributes of its ``tr``.
        table_attrs: Attributes of the ``table``.
        sorted_by: ``(column, "ascending" | "descending")``: the order ``rows`` come in, shown by the header's
            arrow (``aria-sort``).
        titles: Tooltips of the headers, by header.
        descending_first: Headers whose first click sorts largest first (where a larger value is worse).
        cell_classes: A class of the body cells of some columns, by column.
    """
    sortable = "sortable" in table_attrs

    def cls(i: int, is_head: bool) -> str:
        names = (["l"] if i < left else []) + (["num"] if is_head and i < len(numeric) and numeric[i] else [])
        if not is_head and cell_classes and i in cell_classes:
            names.append(cell_classes[i])
        return f" class='{' '.join(names)}'" if names else ""

    def th(i: int, header: str) -> str:
        attrs = cls(i, True)
        if header in descending_first:
            attrs += " data-first='descending'"
        if sorted_by and sorted_by[0] == i:
            attrs += f" aria-sort='{sorted_by[1]}'"
        if titles and header in titles:
            attrs += f" title='{_esc(titles[header])}'"
        label = _header(header)
        if sortable and header:
            label = f"<button type='button' class='sort'>{label}</button>"
        return f"<th{attrs}>{label}</th>"

    def td(i: int, cell: Any) -> str:
        text, key = cell if isinstance(cell, tuple) else (cell, None)
        sort = "" if key is None else f" data-sort='{_esc(key)}'"
        return f"<td{cls(i, False)}{sort}>{text}</td>"

    head = "".join(th(i, h) for i, h in enumerate(headers))
    body = []
    for r, row in enumerate(rows):
        attrs = f" {row_attrs[r]}" if row_attrs and row_attrs[r] else ""
        body.append(f"<tr{attrs}>" + "".join(td(i, c) for i, c in enumerate(row)) + "</tr>")
    return f"<table {table_attrs}><thead><tr>{head}</tr></thead><tbody>{''.join(body)}</tbody></table>"


def _scroll_box(table: str, *, box: str = "hscroll") -> str:
    """``table`` in a box that scrolls it (``hscroll``: sideways; ``scroll``: both ways, at most 80 % of the
    screen's height), after a line that the page's script shows while the table is wider than the box."""
    hint = ("<p class='scrollhint' hidden>→ This table is wider than the screen: scroll it sideways for more "
            "columns.</p>")
    return f"{hint}<div class='{box}'>{table}</div>"


def _page(title: str, body: str) -> str:
    return (f"<!DOCTYPE html>\n<html lang='en'><head><meta charset='utf-8'>"
            f"<meta name='viewport' content='width=device-width, initial-scale=1'><title>{_esc(title)}</title>"
            f"<style>{_STYLE}</style></head><body>{body}<script>{_SCRIPT}</script></body></html>\n")


def region_statistics(levels: Sequence[dict[str, Any]], measures: Sequence[str], *, means: Sequence[str] = (),
                      bins: int = REGIONS_PER_MEASURE) -> list[dict[str, Any]]:
    """Levels grouped by measure region (equal-width bins over the observed range of each measure).

    A region is half-open, ``[low, high)`` per measure (the last one closed), so a level on an edge belongs to
    the upper region only.

    Returns:
        One record per non-empty region: ``ranges`` per measure (the region's edges), ``extent`` per measure
        (its levels' lowest and highest value), ``levels``, mean ``objective``, mean and min ``success_rate``,
        the mean of each of the entry keys ``means`` that every level has (Maze: ``mean_path_length``) and the
        ``worst`` level id; worst regions first.
    """
    if not levels:
        return []
    values = np.array([[lv["measures"][m] for m in measures] for lv in levels], dtype=float)
    edges = [np.linspace(values[:, j].min(), values[:, j].max(), bins + 1) for j in range(len(measures))]
    # side="right": a value on an edge opens the upper region; the clip closes the last region at the maximum.
    keys = np.stack([np.clip(np.searchsorted(e, values[:, j], side="right") - 1, 0, bins - 1)
                     for j, e in enumerate(edges)], axis=1)
    means = [key for key in means if all(key in lv for lv in levels)]
    regions = []
    for key in sorted({tuple(k) for k in keys.tolist()}):
        members = [lv for lv, k in zip(levels, keys.tolist()) if tuple(k) == key]
        worst = max(members, key=lambda lv: (lv["objective"], -lv["success_rate"]))
        region = {
            "ranges": {m: (float(edges[j][key[j]]), float(edges[j][key[j] + 1])) for j, m in enumerate(measures)},
            "extent": {m: (min(float(lv["measures"][m]) for lv in members),
                           max(float(lv["measures"][m]) for lv in members)) for m in measures},
            "levels": len(members),
            "objective": float(np.mean([lv["objective"] for lv in members])),
            "success_rate": float(np.mean([lv["success_rate"] for lv in members])),
            "min_success_rate": float(min(lv["success_rate"] for lv in members)),
            "worst": worst["id"],
        }
        region.update({key: float(np.mean([lv[key] for lv in members])) for key in means})
        regions.append(region)
    regions.sort(key=lambda r: -r["objective"])
    return regions


def _reference_command(collection: dict[str, Any], entry: dict[str, Any], command: str) -> str | None:
    """The reference agent's command for ``entry``: recorded, or the agent's with the agent spec swapped."""
    reference = entry.get("reference") or {}
    if reference.get("reproduce"):
        return reference["reproduce"]
    flag = f"--agent {shlex.quote(collection['agent'])}"
    if collection.get("reference") and command.count(flag) == 1:
        return command.replace(flag, f"--agent {shlex.quote(collection['reference'])}")
    return None


def report_columns(collection: dict[str, Any]) -> list[ReportField]:
    """The domain's own numbers of the entries the report shows: its registration's ``columns`` that every entry
    has as a number, measures excluded; for a domain that declares none (or is not installed), every such key."""
    numbers = _domain_numbers(collection)
    audit = audit_declaration(collection["domain"])
    if audit is not None and audit.columns:
        return [column for column in audit.columns if column.key in numbers]
    return [ReportField(key=key) for key in numbers]


def _domain_numbers(collection: dict[str, Any]) -> list[str]:
    """The domain's own scalar numbers of the entries (mean path length, completion, ...), measures excluded."""
    levels = collection["levels"]
    if not levels:
        return []
    return [key for key, value in levels[0].items()
            if key not in _GENERIC_KEYS and key not in collection["measures"]
            and isinstance(value, (int, float)) and not isinstance(value, bool)
            and all(isinstance(lv.get(key), (int, float)) for lv in levels)]


def _reference_numbers(collection: dict[str, Any]) -> list[str]:
    """Numeric keys of the entries' ``reference`` records (success rate first), the shared seed excluded."""
    levels = collection["levels"]
    if not collection.get("reference") or not levels or not isinstance(levels[0].get("reference"), dict):
        return []
    keys = [k for k, v in levels[0]["reference"].items()
            if k != "seed" and isinstance(v, (int, float)) and not isinstance(v, bool)]
    return sorted(keys, key=lambda k: k != "success_rate")


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

    label = _objective_label(collection)

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
    if not _is_number(elites) or cells <= 0:
        return "?"
    return f"{int(elites):,} of {cells:,} archive cells hold an elite ({elites / cells:.2%})"


def _metadata(c: dict[str, Any], collection_dir: Path) -> str:
    config = c.get("config") or {}
    ranges = ", ".join(f"{m} [{lo:g}, {hi:g}] in {d} cells"
                       for m, (lo, hi), d in zip(c["measures"], c["measure_ranges"], c["archive_dims"]))
    items = [
        ("domain", _esc(c["domain"])),
        ("agent", f"<code>{_esc(c['agent'])}</code>"),
        ("reference", f"<code>{_esc(c['reference'])}</code>" if c.get("reference") else "none"),
        *([("nominal check", _nominal(c))] if "nominal" in c else []),
        ("objective", _esc(c["objective"])),
        ("measures", _esc(ranges)),
        ("preset", _esc(config.get("preset", "?"))),
        ("budget", f"{_esc(config.get('budget', '?'))} real evaluations in the search"),
        ("episodes", f"{_esc(c['episodes'])} per level (re-evaluation)"),
        ("seed", f"{_esc(c.get('run_seed', '?'))} (each level's evaluation seed is in the table)"),
        ("search folder", f"<code>{_esc(_search_folder(c.get('search_dir'), collection_dir))}</code>"),
        ("coverage", _esc(_coverage(c))),
        ("created", _esc(c.get("created", "?"))),
    ]
    audit = audit_declaration(c["domain"])
    items += [(_esc(setting.name), _esc(setting.text(c[setting.key]))) for setting in (audit.settings if audit else ())
              if c.get(setting.key) is not None]
    if c.get("notes"):
        items.append(("notes", _esc(c["notes"])))
    return "<dl class='meta'>" + "".join(f"<dt>{k}</dt><dd>{v}</dd>" for k, v in items) + "</dl>"


def _nominal(c: dict[str, Any]) -> str:
    """The header's text of the audit's nominal check (the agent on the domain's nominal level before the search),
    marked where it failed."""
    record = c["nominal"]
    text = _esc(record_summary(record)) if isinstance(record, dict) else "?"
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
            + "".join(f"<div class='stat'><b>{_esc(v)}</b><span>{_esc(label)}</span></div>" for v, label in tiles)
            + "</div>")


def _command(text: str) -> str:
    # One inline block per word: lines wrap between words, never inside "--layout" at its hyphens.
    words = " ".join(f"<span>{_esc(word)}</span>" for word in text.split(" "))
    return f"<div><code class='cmd'>{words}</code> <button class='copy' type='button'>copy</button></div>"


# ----------------------------------------------------------------------------- the failure numbers
# One failure number per level: its failure rate (1 - success rate). The objective is shown beside it only
# where it is another number (Mario's incompletion, Maze's regret); a regression audit shows the regression
# (the reference's success rate minus the agent's) instead of its [0, 1] score.

FAILURE_RATE = "failure rate"


def _is_regression(c: dict[str, Any]) -> bool:
    return bool(c.get("reference")) and any("regression" in lv for lv in c["levels"])


def _objective_label(c: dict[str, Any]) -> str:
    return str(c["objective"]).replace("_", " ")


def _shows_objective(c: dict[str, Any]) -> bool:
    """Whether the objective needs its own column: not the failure rate itself, nor a regression's score."""
    if _is_regression(c):
        return False
    return not all(abs(lv["objective"] - (1 - lv["success_rate"])) < 1e-9 for lv in c["levels"])


def _failure_rate(record: dict[str, Any]) -> float:
    return 1.0 - record["success_rate"]


def _ranking(c: dict[str, Any]) -> str:
    """The number the levels are ranked by, worst first, as the page names it."""
    return "regression" if _is_regression(c) else _objective_label(c) if _shows_objective(c) else FAILURE_RATE


def _card(c: dict[str, Any], lv: dict[str, Any], collection_dir: Path, columns: Sequence[ReportField],
          formats: dict[str, Callable[[Any], str]], notes: dict[str, str]) -> str:
    """One worst-level card: picture(s), the level's numbers (next to the reference's), its command(s)."""
    reference = lv.get("reference") if _is_regression(c) else None
    pictures = [(c["agent"], lv["image_file"])]
    if reference and reference.get("image_file"):
        pictures.append((c["reference"], reference["image_file"]))

    def figure(name: str, file: Any) -> str:
        path = _collection_file(collection_dir, file)
        picture = _img(path.read_bytes(), alt=path.name) if path else "(no picture)"
        caption = f"<figcaption>{_esc(name)}</figcaption>" if len(pictures) > 1 else ""
        return f"<figure>{picture}{caption}</figure>"

    cell = lambda key, v: "" if v is None else formats.get(key, _formatter([v]))(v)  # noqa: E731
    label = lambda name, key: (f"<td class='l' title='{_esc(notes[key])}'>{_esc(name)}</td>"  # noqa: E731
                               if key in notes else f"<td class='l'>{_esc(name)}</td>")
    rows = _card_rows(c, lv, reference, columns)
    if reference:
        body = "".join(f"<tr>{label(name, key)}<td>{cell(key, v)}</td><td>{cell(key, ref)}</td></tr>"
                       for name, key, v, ref in rows)
        # Role names keep the card narrow; the specs are in the page header and the tooltips.
        head = (f"<tr><th class='l'></th><th title='{_esc(c['agent'])}'>agent</th>"
                f"<th title='{_esc(c['reference'])}'>reference</th></tr>")
        mark = " class='bad'" if lv["regression"] > 0 else ""
        headline = f"#{lv['id']}: <span{mark}>regression {lv['regression']:+.2f}</span>"
    else:
        body = "".join(f"<tr>{label(name, key)}<td>{cell(key, v)}</td></tr>" for name, key, v, _ in rows)
        head = ""
        key, value = ("objective", lv["objective"]) if _shows_objective(c) else ("failure_rate", _failure_rate(lv))
        headline = f"#{lv['id']}: {_esc(_ranking(c))} {cell(key, value)}"
    command = portable_command(lv["reproduce"], lv["level_file"])
    parts = [f"<div class='card'><h3>{headline}</h3><div class='pics'>"
             + "".join(figure(name, file) for name, file in pictures) + "</div>",
             f"<table>{head}{body}</table>", f"<div>seed {_esc(lv['seed'])}, {_esc(lv['episodes'])} episodes:</div>",
             _command(command)]
    reference_command = _reference_command(c, lv, command) if reference else None
    if reference_command:
        parts += ["<div>the reference, same seed:</div>",
                  _command(portable_command(reference_command, lv["level_file"]))]
    return "".join(parts) + "</div>"


def _card_rows(c: dict[str, Any], lv: dict[str, Any], reference: dict[str, Any] | None,
               columns: Sequence[ReportField]) -> list[tuple[str, str, Any, Any]]:
    """A card's table: ``(label, format key, the level's value, the reference's)`` per row. The failure rate is
    a row only where the headline shows another number (a regression, an objective of its own)."""
    ref = reference or {}
    rows = []
    if reference or _shows_objective(c):
        rows.append((FAILURE_RATE, "failure_rate", _failure_rate(lv), _failure_rate(ref) if ref else None))
    rows += [(m, m, v, None) for m, v in lv["measures"].items()]
    rows += [(column.name, column.key, lv[column.key], ref.get(column.key)) for column in columns]
    rows += [(k.replace("_", " "), k, None, ref[k]) for k in (_reference_numbers(c) if ref else ())
             if k not in lv and k != "success_rate"]
    return rows


def _levels_table(c: dict[str, Any], columns_shown: Sequence[ReportField], formats: dict[str, Callable[[Any], str]],
                  notes: dict[str, str]) -> str:
    levels, measures = c["levels"], c["measures"]
    objective = _objective_label(c)
    columns: list[tuple[str, str, Callable[[dict[str, Any]], Any]]] = [("id", "id", lambda lv: lv["id"])]
    if _shows_objective(c):
        columns.append((objective, "objective", lambda lv: lv["objective"]))
    columns.append((FAILURE_RATE, "failure_rate", _failure_rate))
    if _is_regression(c):
        columns.append((f"reference {FAILURE_RATE}", "failure_rate", lambda lv: _failure_rate(lv["reference"])))
        columns += [(f"reference {k.replace('_', ' ')}", k, lambda lv, k=k: lv["reference"].get(k))
                    for k in _reference_numbers(c) if k != "success_rate"]
        columns.append(("regression", "regression", lambda lv: lv.get("regression")))
    columns += [(m, m, lambda lv, m=m: lv["measures"][m]) for m in measures]
    columns += [(column.name, column.key, lambda lv, k=column.key: lv[k]) for column in columns_shown]
    columns += [("seed", "seed", lambda lv: lv["seed"]),
                ("search objective", "search_objective", lambda lv: lv.get("search_objective"))]
    # The domain's columns as on the cards (their declared format, if any); the others suited to their values.
    column_formats = [formats.get(key) or _formatter([get(lv) for lv in levels]) for _, key, get in columns]
    rows, attrs = [], []
    for lv in levels:
        cells = [f(get(lv)) for (_, _, get), f in zip(columns, column_formats)]
        command = portable_command(lv["reproduce"], lv["level_file"])
        # Paths relative to the collection folder, which wrap; the command is the copy button's.
        cells.append(f"{_file_link(lv['level_file'], lv['level_file'])} {_file_link(lv['image_file'], 'picture')} "
                     f"<button class='copy' type='button' data-cmd='{_esc(command)}' "
                     f"title='copy the command: {_esc(command)}'>copy</button>")
        rows.append(cells)
        regression = f" data-r='{lv['regression']!r}'" if "regression" in lv else ""
        # The row's id is the target of the region table's "worst level" links.
        attrs.append(f"id='level-{lv['id']}' data-s='{lv['success_rate']!r}' "
                     f"data-m='{' '.join(repr(float(lv['measures'][m])) for m in measures)}'{regression}")
    headers = [name for name, _, _ in columns] + ["files"]
    numeric = [True] * len(columns) + [False]
    return _scroll_box(_table(
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
        parts.append(f"<label>{_esc(m)} <input type='number' step='any' class='lo' data-j='{j}' "
                     f"placeholder='{min(values):g}' aria-label='{_esc(m)} from'> to "
                     f"<input type='number' step='any' class='hi' data-j='{j}' placeholder='{max(values):g}' "
                     f"aria-label='{_esc(m)} to'></label>")
    parts.append("<button type='button' id='reset'>reset</button> <span id='shown'></span></div>")
    return "".join(parts)


def printed_range(low: float, high: float, values: Sequence[float], decimals: int) -> tuple[str, str]:
    """A region's range along one measure as the region table prints it and its button fills it in.

    ``low`` and ``high`` are the lowest and highest value of the region's levels. The printed ends are rounded
    outward at ``decimals`` (more where needed) so that the range, both ends included, holds exactly the levels
    between ``low`` and ``high`` among ``values``: no other level's value falls in what the rounding added.
    """
    for places in range(decimals, 16):
        step = Decimal(1).scaleb(-places)
        lo = Decimal(repr(float(low))).quantize(step, rounding=ROUND_FLOOR)
        hi = Decimal(repr(float(high))).quantize(step, rounding=ROUND_CEILING)
        if not any(float(lo) <= v < low or high < v <= float(hi) for v in values):
            return str(lo), str(hi)
    return repr(float(low)), repr(float(high))


def _regions(c: dict[str, Any], columns: Sequence[ReportField], formats: dict[str, Callable[[Any], str]],
             notes: dict[str, str]) -> str:
    measures, levels = c["measures"], c["levels"]
    averaged = [column for column in columns if column.mean]
    regression = _is_regression(c)
    regions = region_statistics(levels, measures, means=[column.key for column in averaged]
                                + (["regression"] if regression else []))
    # Counts and buttons first: on a phone they are what shows without scrolling.
    ranking = f"mean {_ranking(c)}"
    headers = ["levels", "", ranking, *([f"mean {FAILURE_RATE}"] if ranking != f"mean {FAILURE_RATE}" else []),
               "worst level", *measures, *(column.mean for column in averaged)]
    values = {m: [float(lv["measures"][m]) for lv in levels] for m in measures}
    decimals = {m: _decimals(values[m]) for m in measures}
    rows = []
    for r in regions:
        printed = {m: printed_range(*r["extent"][m], values[m], decimals[m]) for m in measures}
        lo = " ".join(a for a, _ in printed.values())
        hi = " ".join(b for _, b in printed.values())
        mean = r["regression"] if regression else r["objective"] if _shows_objective(c) else 1 - r["success_rate"]
        rows.append([r["levels"],
                     f"<button type='button' class='region' data-lo='{lo}' data-hi='{hi}'>show</button>",
                     f"{mean:+.3f}" if regression else f"{mean:.3f}",
                     *([f"{1 - r['success_rate']:.3f}"] if ranking != f"mean {FAILURE_RATE}" else []),
                     (f"<a href='#level-{r['worst']}'>#{r['worst']}</a>", r["worst"]),
                     *((a if a == b else f"{a} – {b}", float(a)) for a, b in printed.values()),
                     *(formats[column.key](r[column.key]) for column in averaged)])
    numeric = [True, False] + [True] * (len(headers) - 2)
    table = _table(headers, rows, left=0, numeric=numeric, sorted_by=(2, "descending"),
                   descending_first={ranking, f"mean {FAILURE_RATE}"},
                   titles={**{m: f"the lowest and highest {m} among the region's levels (the regions split each "
                                 f"measure's range into {REGIONS_PER_MEASURE} equal parts)" for m in measures},
                           "worst level": "the region's worst level: opens its row in the table of all levels",
                           **{column.mean: notes[column.key] for column in averaged if column.key in notes}})
    return _scroll_box(table)


def _glossary(c: dict[str, Any]) -> str:
    """One line per term the page uses, and how the worst levels are ordered."""
    objective, episodes = _objective_label(c), _esc(c["episodes"])
    cells = " × ".join(str(int(d)) for d in c["archive_dims"])
    terms = [(FAILURE_RATE, f"the share of a level's {episodes} episodes that the agent failed (1 − success rate), "
                            "measured again after the search with the level's recorded seed.")]
    if _shows_objective(c):
        terms.append((objective, "the audit's objective, which the search maximised to find these levels; "
                                 "measured again like the failure rate."))
    if _is_regression(c):
        terms.append(("regression", "the reference's success rate minus the agent's, on the same seed: above 0, "
                                    "the agent fails more often than the reference."))
    terms += [
        ("search objective", f"the {_esc(objective)} the search recorded when it kept the level: one evaluation "
                             "with another seed. The search keeps the highest values it saw, often lucky ones, so "
                             "this is often higher than the number measured again."),
        ("measures", f"numbers that describe a level ({_esc(', '.join(c['measures']))}); the search looks for "
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
            + "".join(f"<div><dt>{_esc(term)}</dt> <dd>{text}</dd></div>" for term, text in terms) + "</dl>")


def _ties(c: dict[str, Any]) -> str:
    """How levels with the same worst-first number are ordered (the collection's order, :func:`~dsage_ray.audit.
    collection.build_collection`): by success rate, then as the search rated them."""
    ranking = _ranking(c)
    success = "" if ranking == FAILURE_RATE else "with the lower success rate first, then "
    return (f"levels with the same {_esc(ranking)} are listed {success}with the higher search objective first, "
            "then in the search archive's order. Numbers are rounded on the page: levels that look tied may "
            "differ in a later decimal.")


def _notes(c: dict[str, Any], columns: Sequence[ReportField]) -> dict[str, str]:
    """Explanations of the domain's numbers, by key (tooltips of their headers and labels): the columns' own,
    with the collection's settings filled in (Maze: its step limit, which a failed episode counts)."""
    return {column.key: text for column in columns if (text := column.explain(c))}


def check_numbers(c: dict[str, Any]) -> None:
    """Checks that every number the page computes with is one (a collection may come from someone else).

    Raises:
        ValueError: A field that is not what the page needs, named (``level 3: success_rate ...``).
    """
    def number(value: Any, where: str) -> None:
        if not _is_number(value):
            raise ValueError(f"collection.json: {where} is {value!r}, not a number")

    if not isinstance(c.get("measures"), list) or not all(isinstance(m, str) for m in c["measures"]):
        raise ValueError("collection.json: measures is not a list of names")
    for key in ("measure_ranges", "archive_dims", "levels"):
        if not isinstance(c.get(key), list):
            raise ValueError(f"collection.json: {key} is not a list")
    for j, pair in enumerate(c["measure_ranges"]):
        for k, value in enumerate(pair if isinstance(pair, list) and len(pair) == 2 else [pair]):
            number(value, f"measure_ranges[{j}][{k}]")
    for j, value in enumerate(c["archive_dims"]):
        if not isinstance(value, int) or isinstance(value, bool) or value < 1:
            raise ValueError(f"collection.json: archive_dims[{j}] is {value!r}, not a cell count")
    for i, lv in enumerate(c["levels"]):
        if not isinstance(lv, dict) or not isinstance(lv.get("id"), int) or isinstance(lv["id"], bool):
            raise ValueError(f"collection.json: level {i} has no integer id")
        where = f"level {lv['id']}"
        for key in ("objective", "success_rate"):
            number(lv.get(key), f"{where}: {key}")
        if not isinstance(lv.get("measures"), dict):
            raise ValueError(f"collection.json: {where}: measures is not a mapping")
        for m in c["measures"]:
            number(lv["measures"].get(m), f"{where}: measure {m!r}")
        if c.get("reference") and "regression" in lv:
            number(lv["regression"], f"{where}: regression")
            number((lv.get("reference") or {}).get("success_rate"), f"{where}: reference success_rate")
        for key in ("level_file", "image_file", "reproduce"):
            if not isinstance(lv.get(key), str):
                raise ValueError(f"collection.json: {where}: {key} is not text")


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
        lead = (f"Levels where <code>{_esc(c['agent'])}</code> does worse than <code>{_esc(c['reference'])}</code>, "
                f"both evaluated with the same seeds; largest regression first.")
    else:
        title = f"Audit of {c['agent']}"
        lead = f"Levels where <code>{_esc(c['agent'])}</code> fails, worst first."
    if _nominal_failed(c):
        lead += (" <span class='bad'>The agent failed its nominal check (see Run below): the failures here may be "
                 "artefacts of how it was played.</span>")
    lead += (f" Every number was measured again after the search with the level's recorded seed and "
             f"{_esc(c['episodes'])} episodes; each level's command prints it again. The terms are explained "
             f"<a href='#terms'>below</a>.")
    parts = [f"<h1>{_esc(title)}</h1><p class='lead'>{lead}</p>", "<h2>Failure diversity</h2>", _summary(summary),
             "<h2>Run</h2>", _metadata(c, collection_dir), "<h2>Terms</h2>", _glossary(c)]
    heatmaps = heatmap_pngs(c)
    if heatmaps:
        parts += ["<h2>Where the levels are</h2>",
                  f"<p class='lead'>Each archive cell's colour is the highest {_esc(_objective_label(c))} among its "
                  "levels; grey cells hold none.</p><div class='figs'>",
                  _img(heatmaps["zoomed"], alt="heatmap, zoomed"), _img(heatmaps["full"], alt="heatmap, full range"),
                  "</div>"]
    shown = levels[:WORST_SHOWN]
    # One number format per key across the collection, so the cards line up with each other and the table.
    references = [lv.get("reference") or {} for lv in levels]
    formats = {key: _formatter([lv.get(key) for lv in levels] + [r.get(key) for r in references])
               for key in ["objective", *(column.key for column in columns), *_reference_numbers(c)]}
    formats["failure_rate"] = _formatter([_failure_rate(lv) for lv in levels]
                                         + [_failure_rate(r) for r in references if _is_number(r.get("success_rate"))])
    formats.update({column.key: lambda v, column=column: _esc(column.text(v)) for column in columns if column.format})
    formats.update({m: _formatter([lv["measures"][m] for lv in levels]) for m in c["measures"]})
    # Two pictures per card (the reference's too) need wider cards.
    wide = " wide" if any((lv.get("reference") or {}).get("image_file") for lv in shown) else ""
    # Where a number needs a sentence (Maze's 648 = a failed episode's step limit), it comes before the cards
    # and tables that show it, and again as their headers' tooltips.
    explained = "".join(f"<p class='lead note'><b>{_esc(column.name)}</b>: {_esc(notes[column.key])}.</p>"
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
    atomic_write_text(path, _page(title, "".join(parts)))
    return path


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
            return _esc(file)
        href = urllib.parse.quote(Path(os.path.relpath(collection_dir / file, path.parent)).as_posix())
        return f"<a href='{href}'>{_esc(file)}</a>"

    a, b = comparison["agent_a"], comparison["agent_b"]
    rows = comparison["levels"]
    summary = comparison["summary"]
    columns = comparison.get("columns", [])
    number = {c["key"]: _formatter([r[f"{c['key']}_{role}"] for r in rows for role in "ab"]) for c in columns}
    title = f"Compare {a} vs {b}"
    parts = [
        f"<h1>{_esc(title)}</h1><p class='lead'>A = <code>{_esc(a)}</code>, B = <code>{_esc(b)}</code>, on the "
        f"{len(rows)} levels of <code>{_esc(collection_dir)}</code>, each with its recorded seed and "
        f"{_esc(comparison['episodes_note'])}.</p>",
        _table(["", "A", "B"], [
            ["mean success rate", f"{summary['success_a']:.3f}", f"{summary['success_b']:.3f}"],
            *([_esc(c["mean"]), number[c["key"]](summary[f"{c['key']}_a"]), number[c["key"]](summary[f"{c['key']}_b"])]
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
            changes = "".join(f"; {_esc(c['label'])} {number[c['key']](row[c['key'] + '_a'])} → "
                              f"{number[c['key']](row[c['key'] + '_b'])}" for c in columns)
            parts.append(f"<div class='card'>{_img(images[row['id']], alt=alt)}"
                         f"<div>#{_esc(row['id'])}: success A {row['success_a']:.2f} → B {row['success_b']:.2f}"
                         f"{changes}</div></div>")
    parts.append("</div><h2>All levels (B − A)</h2><p class='lead'>Click a column header to sort.</p>")
    classes = [f"class='{r['verdict']}'" if r["verdict"] in ("worse", "better") else "" for r in rows]
    headers = ["id", "level", "success A", "success B", "Δ success",
               *(f"{c['label']} {x}" for c in columns for x in ("A", "B", "Δ")), "verdict"]
    cells = [[_esc(r["id"]), link(r["level_file"]),
              f"{r['success_a']:.2f}", f"{r['success_b']:.2f}", f"{r['success_b'] - r['success_a']:+.2f}",
              *(text for c in columns for text in (
                  number[c["key"]](r[c["key"] + "_a"]), number[c["key"]](r[c["key"] + "_b"]),
                  f"{r[c['key'] + '_b'] - r[c['key'] + '_a']:+.3g}")),
              _esc(r["verdict"])] for r in rows]
    parts.append(_scroll_box(_table(
        headers, cells, left=0, numeric=[True, False, *([True] * (len(headers) - 3)), False],
        row_attrs=classes, sorted_by=(4, "ascending"))))
    atomic_write_text(path, _page(title, "".join(parts)))
    return path
