"""Every config key on one line: what ``dsage-ray config`` prints and docs/CONFIG.md tabulates.

Both read the config dataclasses' own fields (:func:`dsage_ray.config.key` metadata), so the docs cannot drift
from the code: ``python -m dsage_ray.config_listing > docs/CONFIG.md`` writes the page, and a test compares it.
"""

from __future__ import annotations

import dataclasses
import json
import typing
from typing import Any, Iterator, Literal

from dsage_ray.config import REMOVED_KEYS, RENAMED_KEYS, ExperimentalConfig, RunConfig, shown_value
from dsage_ray.domains.registry import DEFAULT_DOMAIN, domain_names, get_domain

#: The sections of the run config, in the order they are listed (``experimental`` last, apart).
RUN_SECTIONS = ("surrogate", "qd", "selection", "ray")


@dataclasses.dataclass(frozen=True)
class KeyLine:
    """One config key as it is listed.

    Attributes:
        key: Its full dotted name (``surrogate.channels``).
        default: Its default, as a config file would write it.
        values: The values it takes.
        status: ``paper``, ``tool``, ``default-on``, ``opt-in``, ``experimental`` or ``domain`` (a domain section's
            key).
        note: What it does, and where measured, what it did.
    """

    key: str
    default: str
    values: str
    status: str
    note: str


def key_lines(*, domain: str | None = None, experimental: bool = False) -> list[KeyLine]:
    """The run keys, then ``domain``'s section keys (None: none), then, with ``experimental``, the experimental ones."""
    config = RunConfig(domain=domain or DEFAULT_DOMAIN)
    lines = list(_fields(config, "", skip=(*RUN_SECTIONS, "experimental", "sections")))
    for name in RUN_SECTIONS:
        lines.extend(_fields(getattr(config, name), f"{name}."))
    if domain is not None:
        lines.extend(_fields(config.section(domain), f"{domain}.", status="domain"))
    if experimental:
        lines.extend(_fields(ExperimentalConfig(), "experimental."))
    return lines


def format_lines(lines: list[KeyLine]) -> str:
    """Aligned columns: key, default, values, status, note."""
    widths = [max(len(getattr(line, column)) for line in lines) for column in ("key", "default", "values", "status")]
    return "\n".join(f"{line.key:<{widths[0]}}  {line.default:<{widths[1]}}  {line.values:<{widths[2]}}  "
                     f"{line.status:<{widths[3]}}  {line.note}".rstrip() for line in lines)


def markdown() -> str:
    """docs/CONFIG.md: the run keys, each domain's section, the experimental keys, and the renamed and removed ones."""
    run = key_lines()
    parts = ["# Configuration keys", "",
             "Generated from the config's fields by `python -m dsage_ray.config_listing > docs/CONFIG.md` (a test keeps "
             "it equal); `dsage-ray config` prints the same lines. A key is set in a TOML/JSON config file, with `--set "
             "KEY=VALUE`, or as a `tune.grid_search` axis of the same dotted name. Presets and variants set several at "
             "once (`dsage-ray config FILE --preset cpu` prints what a run resolves to).", "",
             "Status: **paper** — the paper's algorithm or value; **tool** — how the tool runs, not what it finds; "
             "**default-on** — beyond the paper, on in the presets or audits the note names; **opt-in** — beyond the "
             "paper, measured to help where the note says, not yet on in a preset; **experimental** — beyond the paper, "
             "off, measured as the note says; **domain** — a key of the domain's own section.", "",
             f"## Run keys ({len(run)})", "", _table(run)]
    # The page documents the package: plug-in domains installed beside it document their own sections.
    shipped = [name for name in domain_names() if get_domain(name).domain.startswith("dsage_ray.")]
    for name in shipped:
        section = key_lines(domain=name)[len(run):]
        parts += ["", f"## The `{name}` section ({len(section)}, with `--domain {name}`)", "", _table(section)]
    experimental = key_lines(experimental=True)[len(run):]
    parts += ["", f"## Experimental ({len(experimental)}, listed with `--experimental`)", "", _table(experimental),
              "", "## Renamed keys", "",
              "No release had these names; they still read because commands in docs/results/ use them.", "",
              "| old name | new name |", "|---|---|",
              *(f"| `{old}` | `{new}` |" for old, new in RENAMED_KEYS.items()),
              "", "## Removed keys", "",
              "Kept for the commands in docs/results/ that set them: the value listed loads as before; any other value "
              "is refused with the reason, since today's code would run something else. Any other key that is gone is "
              "an unknown key (docs/DECISIONS.md lists what was tried and dropped).", "",
              "| key | loads at | why |", "|---|---|---|",
              *(f"| `{key}` | {', '.join(f'`{shown_value(v)}`' for v in removed.accepted) or 'any value'} | "
                f"{removed.why} |" for key, removed in REMOVED_KEYS.items())]
    return "\n".join(parts) + "\n"


def _fields(section: Any, prefix: str, *, skip: tuple[str, ...] = (), status: str = "") -> Iterator[KeyLine]:
    hints = typing.get_type_hints(type(section))
    for field in dataclasses.fields(section):
        if field.name in skip:
            continue
        meta = field.metadata
        yield KeyLine(key=prefix + field.name, default=_default(getattr(section, field.name)),
                      values=meta.get("values") or _values_of(hints[field.name]),
                      status=status or meta.get("status", ""), note=meta.get("note", ""))


def _default(value: Any) -> str:
    return json.dumps(list(value) if isinstance(value, tuple) else value)


def _values_of(annotation: Any) -> str:
    """What a field's type says about its values: the names of a ``Literal``, else the type's name."""
    if typing.get_origin(annotation) is Literal:
        return ", ".join(map(str, typing.get_args(annotation)))
    if annotation is bool:
        return "true, false"
    if typing.get_origin(annotation) is tuple:
        return "a list"
    return getattr(annotation, "__name__", str(annotation))


def _table(lines: list[KeyLine]) -> str:
    rows = ["| key | default | values | status | note |", "|---|---|---|---|---|"]
    rows += [f"| `{line.key}` | `{line.default}` | {line.values} | {line.status} | {line.note} |" for line in lines]
    return "\n".join(rows)


if __name__ == "__main__":
    print(markdown(), end="")
