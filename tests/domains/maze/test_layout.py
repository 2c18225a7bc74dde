import numpy as np
import pytest

from dsage_ray.domains.maze.layout import LayoutError, format_layout, load_layout, parse_layout
from dsage_ray.domains.maze.level import MazeLevel

from .conftest import DATA


def test_parse_without_marks_uses_furthest_pair():
    level = parse_layout("...\n.#.\n...\n\n  \n")
    assert level.walls.tolist() == [[False] * 3, [False, True, False], [False] * 3]
    assert (level.start, level.goal) == ((0, 0), (2, 2))


def test_parse_with_marks_and_trailing_whitespace():
    level = parse_layout("S.#  \n..G\n")
    assert (level.start, level.goal) == ((0, 0), (1, 2))
    assert level.num_walls == 1 and level.optimal_path_length == 3


@pytest.mark.parametrize("name", ["labyrinth13.txt", "small.txt", "corridor_sg.txt"])
def test_data_files_load_and_round_trip(name):
    level = load_layout(DATA / name)
    assert level.valid
    again = parse_layout(format_layout(level))
    assert np.array_equal(again.walls, level.walls)
    assert (again.start, again.goal) == (level.start, level.goal)


def test_labyrinth_shape():
    level = load_layout(DATA / "labyrinth13.txt")
    assert (level.height, level.width) == (13, 13)
    assert (level.start, level.goal) == ((0, 0), (6, 6))
    assert level.optimal_path_length > 40  # it winds: the straight-line distance is 12


def test_format_writes_s_and_g_and_rejects_invalid():
    text = format_layout(MazeLevel.from_bitmap(np.zeros((2, 3))))
    assert text == "S..\n..G\n"
    with pytest.raises(ValueError):
        format_layout(MazeLevel.from_bitmap(np.ones((2, 2))))


@pytest.mark.parametrize(
    "text, line, problem",
    [
        ("", 0, "empty layout"),
        ("\n\n  \n", 0, "empty layout"),
        ("...\n..\n...\n", 2, "ragged rows"),
        ("...\n.x.\n", 2, "unknown character 'x' in column 2"),
        ("##\n##\n", 2, "no empty cell"),
        ("S..\n...\n", 1, "'S' without 'G'"),
        ("...\n..G\n", 2, "'G' without 'S'"),
        ("S.S\n..G\n", 1, "more than one 'S'"),
        ("S..\nG.G\n", 2, "more than one 'G'"),
        ("S#.\n##G\n", 2, "unreachable"),
        (".#\n#.\n", 2, "no two connected empty cells"),
        ("....\n", 1, "at least 2x2"),
    ],
)
def test_bad_layouts_name_source_line_and_problem(text, line, problem):
    with pytest.raises(LayoutError) as info:
        parse_layout(text, source="bad.txt")
    message = str(info.value)
    assert message.startswith("bad.txt:" if line == 0 else f"bad.txt:{line}:"), message
    assert problem in message


def test_load_layout_errors_name_the_file(tmp_path):
    path = tmp_path / "ragged.txt"
    path.write_text("...\n....\n")
    with pytest.raises(LayoutError, match=r"ragged\.txt:2: ragged rows"):
        load_layout(path)
    with pytest.raises(LayoutError, match="missing.txt: cannot read layout"):
        load_layout(tmp_path / "missing.txt")
    assert issubclass(LayoutError, ValueError)
