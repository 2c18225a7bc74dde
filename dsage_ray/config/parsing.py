"""Reading config values: dotted keys, a value checked against its field's type, a ``--set key=value``, a config
file, and how a message shows a value or suggests a key."""

from __future__ import annotations

import difflib
import functools
import json
import tomllib
import types
import typing
from pathlib import Path
from typing import Any, Literal, Mapping

import numpy as np

from dsage_ray.config.schema import ConfigError
from dsage_ray.errors import did_you_mean


def read_config_file(path: str | Path) -> dict[str, Any]:
    """The dotted keys a TOML or JSON config file sets, unvalidated.

    Raises:
        ConfigError: An unreadable file, or one that is not valid TOML/JSON.
    """
    path = Path(path)
    try:
        text = path.read_text()
    except OSError as exc:
        raise ConfigError(f"cannot read config file {path}: {exc.strerror}") from None
    try:
        data = json.loads(text) if path.suffix == ".json" else tomllib.loads(text)
    except (tomllib.TOMLDecodeError, json.JSONDecodeError) as exc:
        raise ConfigError(f"{path}: not valid {'JSON' if path.suffix == '.json' else 'TOML'}: {exc}") from None
    return flatten(data)


def flatten(values: Mapping[str, Any], prefix: str = "") -> dict[str, Any]:
    """``{"a": {"b": 1}}`` → ``{"a.b": 1}``; already-dotted keys pass through."""
    flat: dict[str, Any] = {}
    for key, value in values.items():
        dotted = f"{prefix}{key}"
        if isinstance(value, Mapping):
            flat.update(flatten(value, dotted + "."))
        else:
            flat[dotted] = value
    return flat


def dotted_value(obj: Any, dotted: str) -> Any:
    for part in dotted.split("."):
        obj = getattr(obj, part)
    return obj


def key_hint(key: str, known: Mapping[str, Any]) -> str:
    """What to say about an unknown dotted ``key``: the closest known keys, else what there is."""
    close = difflib.get_close_matches(key, list(known), n=3, cutoff=0.6)
    if close:
        return "did you mean " + " or ".join(close) + "?"
    section = key.rsplit(".", 1)[0] + "." if "." in key else ""
    same_section = [k for k in known if section and k.startswith(section)]
    if same_section:
        return "keys of that section: " + ", ".join(same_section)
    return "sections and keys: " + ", ".join(sorted({k.split(".", 1)[0] for k in known}))


def not_a_choice(key: str, value: Any, choices: tuple[Any, ...]) -> str:
    listed = ", ".join(map(repr, choices[:-1])) + f" or {choices[-1]!r}" if len(choices) > 1 else repr(choices[0])
    return f"{key}: must be {listed} (got {value!r}{did_you_mean(value, choices)})"


@functools.cache
def field_types(cls: type) -> dict[str, Any]:
    return typing.get_type_hints(cls)


def coerce(key: str, value: Any, annotation: Any) -> Any:
    """Checks ``value`` against a field annotation, converting lists to tuples and ints to floats."""
    if isinstance(value, np.generic):
        value = value.item()
    origin = typing.get_origin(annotation)
    args = typing.get_args(annotation)
    if origin in (typing.Union, types.UnionType):
        for option in args:
            try:
                return coerce(key, value, option)
            except ConfigError:
                continue
        raise ConfigError(f"{key}: expected {annotation}, got {value!r}")
    if annotation is type(None):
        if value is None:
            return None
        raise ConfigError(f"{key}: expected None, got {value!r}")
    if origin is tuple:
        if not isinstance(value, (list, tuple)):
            raise ConfigError(f"{key}: expected a list, got {value!r}")
        if len(args) == 2 and args[1] is Ellipsis:
            return tuple(coerce(key, v, args[0]) for v in value)
        if len(args) != len(value):
            raise ConfigError(f"{key}: expected {len(args)} values, got {len(value)}")
        return tuple(coerce(key, v, a) for v, a in zip(value, args))
    if origin is Literal:
        if value in args:
            return value
        raise ConfigError(not_a_choice(key, value, args))
    if annotation is bool:
        if isinstance(value, bool):
            return value
        raise ConfigError(f"{key}: expected true/false, got {value!r}")
    if annotation is int:
        if isinstance(value, int) and not isinstance(value, bool):
            return value
        if isinstance(value, float) and value.is_integer():
            return int(value)
        raise ConfigError(f"{key}: expected an integer, got {value!r}")
    if annotation is float:
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            return float(value)
        raise ConfigError(f"{key}: expected a number, got {value!r}")
    if annotation is str:
        if isinstance(value, str):
            return value
        raise ConfigError(f"{key}: expected a string, got {value!r}")
    return value


def shown_value(value: Any) -> str:
    """A config value as a message shows it: numbers plainly (600, not 600.0), the rest as JSON."""
    is_number = isinstance(value, (int, float)) and not isinstance(value, bool)
    return f"{value:g}" if is_number else json.dumps(value)


def parse_override(text: str) -> tuple[str, Any]:
    """Parses ``key=value`` from the command line; the value is read as TOML, else kept as a string."""
    if "=" not in text:
        raise ConfigError(f"--set {text!r}: expected key=value")
    key, raw = (part.strip() for part in text.split("=", 1))
    try:
        value = tomllib.loads(f"v = {raw}")["v"]
    except tomllib.TOMLDecodeError:
        value = raw
    return key, value
