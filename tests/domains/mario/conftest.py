"""Shared fixtures for the Mario tests: skip cleanly when Java, JPype or the jar is missing."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest


def _java_missing_reason() -> str | None:
    try:
        import jpype  # noqa: F401
    except ImportError:
        return "JPype is not installed (pip install jpype1)"
    if shutil.which("java") is None:
        return "no Java runtime on PATH (install a JDK 17)"
    try:
        from dsage_ray.domains.mario.simulator import jar_path

        jar_path()
    except Exception as exc:  # noqa: BLE001 - any failure here means "cannot run Mario"
        return f"Mario AI jar unavailable: {exc}"
    return None


JAVA_MISSING = _java_missing_reason()
needs_java = pytest.mark.skipif(JAVA_MISSING is not None, reason=JAVA_MISSING or "")
needs_javac = pytest.mark.skipif(shutil.which("javac") is None,
                                 reason="no javac: the deterministic A* timer cannot be compiled")


def level_rows(width: int = 24) -> list[list[str]]:
    """A flat level: sky above two rows of ground, ``width`` columns."""
    rows = [["-"] * width for _ in range(16)]
    for row in (14, 15):
        rows[row] = ["X"] * width
    return rows


def join(rows: list[list[str]]) -> str:
    return "\n".join("".join(r) for r in rows)


@pytest.fixture
def flat_level() -> str:
    """24 columns of flat ground with four coins at small/large Mario's height."""
    rows = level_rows(24)
    for col in range(6, 10):
        rows[13][col] = "o"
    return join(rows)


@pytest.fixture
def obstacle_level() -> str:
    """A short level that needs jumps: a gap, a pipe, a goomba and some floating bricks."""
    rows = level_rows(40)
    for col in (12, 13, 14):  # a 3-tile gap
        rows[14][col] = rows[15][col] = "-"
    for row in (12, 13):  # a 2-high pipe
        rows[row][20] = rows[row][21] = "t"
    rows[13][26] = "g"
    for col in range(28, 32):
        rows[10][col] = "S"
    rows[10][30] = "!"
    return join(rows)


@pytest.fixture
def tmp_level_file(tmp_path: Path, flat_level: str) -> Path:
    path = tmp_path / "flat.txt"
    path.write_text(flat_level + "\n")
    return path


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(0)
