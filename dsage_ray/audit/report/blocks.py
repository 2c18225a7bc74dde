"""The HTML blocks the audit's pages are built of: escaping, links to a collection's own files, pictures, number
formats, tables, and the page around them (its CSS and script are package data, ``assets/report.css`` and
``assets/report.js``).

A collection may come from someone else, so every field put into a page goes through :func:`esc`, and a file a
field names is linked, or its picture embedded, only when the name is a relative path inside the collection
folder (:func:`collection_href`, :func:`collection_file`).
"""

from __future__ import annotations

import base64
import functools
import html
import io
import math
import re
import shlex
import urllib.parse
from importlib import resources
from pathlib import Path, PurePosixPath
from typing import Any, Callable, Collection, Sequence


@functools.cache
def asset(name: str) -> str:
    """The text of one of the pages' assets (``report.css``, ``report.js``), read once."""
    return resources.files(__package__).joinpath("assets", name).read_text(encoding="utf-8")


def esc(value: Any) -> str:
    """``value`` as HTML text, quotes included (safe in an attribute too)."""
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


def collection_file(collection_dir: Path, name: Any) -> Path | None:
    """The collection's own file that a field names (:func:`collection_href`'s rule, and no symbolic link out
    of the folder), or None: the page embeds no other file of the disk."""
    if collection_href(name) is None:
        return None
    root = collection_dir.resolve()
    path = (root / name).resolve()
    return path if path.is_relative_to(root) and path.is_file() else None


def file_link(name: Any, text: str) -> str:
    """``text`` linked to the collection's file ``name``; plain text (the name) where it is not one."""
    href = collection_href(name)
    if href is None:
        return f"<span title='not linked: not a file inside the collection folder'>{esc(name)}</span>"
    return f"<a href='{href}'>{esc(text)}</a>"


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


def compact_png(data: bytes) -> bytes:
    """``data`` re-encoded with a 256-colour palette when that is smaller: figures of flat colours and one
    colour bar lose nothing visible and shrink about threefold, which is what keeps the page light."""
    from PIL import Image

    buffer = io.BytesIO()
    Image.open(io.BytesIO(data)).convert("RGB").quantize(colors=256, method=Image.Quantize.MEDIANCUT).save(
        buffer, format="PNG", optimize=True)
    return min(data, buffer.getvalue(), key=len)


def img_tag(data: bytes, *, alt: str) -> str:
    encoded = base64.b64encode(compact_png(data)).decode("ascii")
    return f"<img src='data:image/png;base64,{encoded}' alt='{esc(alt)}'>"


def is_number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


def column_decimals(values: Sequence[Any]) -> int:
    """Decimals of a column: none for integers, else suited to the column's magnitude."""
    numbers = [float(v) for v in values if is_number(v)]
    if all(v.is_integer() for v in numbers):
        return 0
    top = max(abs(v) for v in numbers)
    return 3 if top < 10 else 2 if top < 100 else 1


def number_format(values: Sequence[Any]) -> Callable[[Any], str]:
    """One number format per column (:func:`column_decimals`); HTML, so a value that is not a number is escaped."""
    decimals = column_decimals(values)

    def text(value: Any) -> str:
        if value is None:
            return ""
        return f"{float(value):.{decimals}f}" if is_number(value) else esc(value)

    return text


def header_html(text: str) -> str:
    """A header's HTML: may wrap after an underscore, so "optimal_path_length" needs no wide column."""
    return esc(text).replace("_", "_<wbr>")


def html_table(headers: Sequence[str], rows: Sequence[Sequence[Any]], *, left: int = 0,
               numeric: Sequence[bool] = (), row_attrs: Sequence[str] | None = None,
               table_attrs: str = "class='sortable'", sorted_by: tuple[int, str] | None = None,
               titles: dict[str, str] | None = None, descending_first: Collection[str] = (),
               cell_classes: dict[int, str] | None = None) -> str:
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
            attrs += f" title='{esc(titles[header])}'"
        label = header_html(header)
        if sortable and header:
            label = f"<button type='button' class='sort'>{label}</button>"
        return f"<th{attrs}>{label}</th>"

    def td(i: int, cell: Any) -> str:
        text, key = cell if isinstance(cell, tuple) else (cell, None)
        sort = "" if key is None else f" data-sort='{esc(key)}'"
        return f"<td{cls(i, False)}{sort}>{text}</td>"

    head = "".join(th(i, h) for i, h in enumerate(headers))
    body = []
    for r, row in enumerate(rows):
        attrs = f" {row_attrs[r]}" if row_attrs and row_attrs[r] else ""
        body.append(f"<tr{attrs}>" + "".join(td(i, c) for i, c in enumerate(row)) + "</tr>")
    return f"<table {table_attrs}><thead><tr>{head}</tr></thead><tbody>{''.join(body)}</tbody></table>"


def scroll_box(table: str, *, box: str = "hscroll") -> str:
    """``table`` in a box that scrolls it (``hscroll``: sideways; ``scroll``: both ways, at most 80 % of the
    screen's height), after a line that the page's script shows while the table is wider than the box."""
    hint = ("<p class='scrollhint' hidden>→ This table is wider than the screen: scroll it sideways for more "
            "columns.</p>")
    return f"{hint}<div class='{box}'>{table}</div>"


def html_page(title: str, body: str) -> str:
    """A whole page: ``body`` with the CSS and the script inline, so that it opens anywhere with no network.

    The script sorts every ``table.sortable`` (its headers are buttons, so the keyboard reaches them; a cell's
    ``data-sort``, where it has one, is its sort key), shows the scroll hints, and filters the table with id
    ``levels`` when the page has one.
    """
    return (f"<!DOCTYPE html>\n<html lang='en'><head><meta charset='utf-8'>"
            f"<meta name='viewport' content='width=device-width, initial-scale=1'><title>{esc(title)}</title>"
            f"<style>{asset('report.css')}</style></head><body>{body}<script>{asset('report.js')}</script>"
            "</body></html>\n")


def command_block(text: str) -> str:
    """A shell command to read and a button that copies it."""
    # One inline block per word: lines wrap between words, never inside "--layout" at its hyphens.
    words = " ".join(f"<span>{esc(word)}</span>" for word in text.split(" "))
    return f"<div><code class='cmd'>{words}</code> <button class='copy' type='button'>copy</button></div>"
