"""Plain-text maze layouts: ``#`` wall, ``.`` empty, optional ``S``/``G``; interior only.

Example (the border wall is implied)::

    S..#
    .#..
    ...G

Without ``S`` and ``G`` the start and goal are the furthest connected pair (SPEC: the Maze).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from dsage_ray.domains.maze.level import MazeLevel
from dsage_ray.errors import InputError

_WALL, _EMPTY, _START, _GOAL = "#", ".", "S", "G"


class LayoutError(InputError):
    """A malformed layout; the message names the source, the line and the problem."""


def parse_layout(text: str, *, source: str = "<string>") -> MazeLevel:
    """Parses a layout into a level.

    Trailing whitespace on a line and blank lines after the grid are ignored.

    Args:
        text: The layout.
        source: What to call the text in error messages (usually its path).

    Raises:
        LayoutError: Empty text, ragged rows, unknown characters, no empty cell, a start without a
            goal (or the reverse), more than one start or goal, or a goal unreachable from the start.
    """
    lines = [line.rstrip() for line in text.splitlines()]
    while lines and not lines[-1]:
        lines.pop()
    if not lines:
        raise LayoutError(f"{source}: empty layout (no rows)")

    def fail(lineno: int, problem: str) -> LayoutError:
        return LayoutError(f"{source}:{lineno}: {problem}")

    width = len(lines[0])
    marks: dict[str, tuple[int, int, int]] = {}  # mark -> (row, col, line number)
    for row, line in enumerate(lines):
        lineno = row + 1
        if len(line) != width:
            raise fail(lineno, f"ragged rows: this row has {len(line)} cells, line 1 has {width}")
        for col, char in enumerate(line):
            if char in (_START, _GOAL):
                if char in marks:
                    raise fail(lineno, f"more than one {char!r} (first on line {marks[char][2]})")
                marks[char] = (row, col, lineno)
            elif char not in (_WALL, _EMPTY):
                raise fail(lineno, f"unknown character {char!r} in column {col + 1} (expected '#', '.', 'S' or 'G')")

    last = len(lines)
    if len(lines) < 2 or width < 2:
        raise fail(last, f"a maze needs at least 2x2 cells, got {len(lines)}x{width}")
    walls = np.array([[char == _WALL for char in line] for line in lines], dtype=bool)
    if walls.all():
        raise fail(last, "no empty cell")
    if (_START in marks) != (_GOAL in marks):
        have, missing = (_START, _GOAL) if _START in marks else (_GOAL, _START)
        raise fail(marks[have][2], f"{have!r} without {missing!r}: give both start and goal, or neither")

    if _START in marks:
        start, goal = marks[_START][:2], marks[_GOAL][:2]
        level = MazeLevel.from_bitmap(walls, start=start, goal=goal)
        if not level.valid:
            raise fail(marks[_GOAL][2], f"goal {goal} is unreachable from start {start}")
        return level
    level = MazeLevel.from_bitmap(walls)
    if not level.valid:
        raise fail(last, "no two connected empty cells: nowhere to put a start and a goal")
    return level


def load_layout(path: str | Path) -> MazeLevel:
    """Reads and parses a layout file.

    Raises:
        LayoutError: The file cannot be read or is malformed.
    """
    path = Path(path)
    try:
        text = path.read_text()
    except (OSError, UnicodeDecodeError) as exc:
        reason = exc.strerror if isinstance(exc, OSError) and exc.strerror else str(exc)
        raise LayoutError(f"{path}: cannot read layout: {reason}") from None
    return parse_layout(text, source=str(path))


def format_layout(level: MazeLevel) -> str:
    """The layout text of ``level``, always with ``S`` and ``G``; :func:`parse_layout` round-trips it.

    Raises:
        ValueError: The level has no start and goal (an invalid level).
    """
    if level.start is None or level.goal is None:
        raise ValueError("cannot format a level without a start and a goal")
    grid = np.where(level.walls, _WALL, _EMPTY).astype("<U1")
    grid[level.start] = _START
    grid[level.goal] = _GOAL
    return "\n".join("".join(row) for row in grid) + "\n"
