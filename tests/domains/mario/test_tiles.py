"""Tile vocabulary, level validation and the human level data."""

from __future__ import annotations

import numpy as np
import pytest

from dsage_ray.domains.mario import tiles
from dsage_ray.domains.mario.tiles import LevelError, load_level, to_array, to_string, validate_level

from .conftest import join, level_rows


def test_vocabulary_matches_spec_order():
    assert "".join(tiles.TILES) == "-*ygkrtS!@FX%M|o#"
    assert tiles.NUM_TILES == 17


def test_round_trip_between_text_and_indices(flat_level):
    array = to_array(flat_level)
    assert array.shape == (16, 24) and array.dtype == np.int64
    assert to_string(array) == flat_level
    assert tiles.indices_to_string(array) == flat_level
    assert to_array(flat_level + "\n").tolist() == array.tolist()  # a file's trailing newline is fine
    assert validate_level(flat_level.splitlines()) == flat_level.splitlines()


@pytest.mark.parametrize("level, message", [
    ("", "empty"),
    ("-" * 10, "16 rows"),
    ("\n".join(["--"] * 15), "16 rows"),
    ("\n".join(["-"] * 16), "at least 2 columns"),
    ("\n".join(["---"] * 15 + ["--"]), "not rectangular"),
    ("\n".join(["---"] * 15 + ["-Z-"]), "unknown tile character 'Z' at row 15, column 1"),
    ("\n".join(["---"] * 15 + ["-x-"]), "unknown tile character 'x'"),  # VGLC path overlay, not a tile
])
def test_bad_levels_are_rejected_with_clear_messages(level, message):
    with pytest.raises(LevelError, match=message):
        validate_level(level)


def test_bad_index_arrays_are_rejected():
    with pytest.raises(LevelError, match="outside 0..16"):
        validate_level(np.full((16, 4), 17))
    with pytest.raises(LevelError, match="integer"):
        validate_level(np.zeros((16, 4)))
    with pytest.raises(LevelError, match="2-D"):
        validate_level(np.zeros((2, 16, 4), dtype=int))
    assert issubclass(LevelError, ValueError)


def test_sky_tiles_counts_non_empty_tiles_in_rows_0_to_8():
    rows = level_rows(10)
    rows[0][0] = "S"
    rows[8][3] = "o"
    rows[9][3] = "S"  # row 9 is not sky
    assert tiles.sky_tiles(to_array(join(rows))) == 2


def test_load_level_names_the_file(tmp_path, tmp_level_file):
    assert load_level(tmp_level_file).shape == (16, 24)
    bad = tmp_path / "bad.txt"
    bad.write_text("--\n--\n")
    with pytest.raises(LevelError, match="bad.txt: level must have 16 rows"):
        load_level(bad)
    with pytest.raises(LevelError, match="cannot read level file"):
        load_level(tmp_path / "missing.txt")


def test_human_levels_are_mapped_with_two_sky_rows():
    from dsage_ray.domains.mario.human_levels import human_level_array, human_level_text, human_windows

    raw = "".join(human_level_text())
    full = human_level_array()
    assert full.shape == (16, 7294)
    assert not full[:2].any()  # the added sky rows are empty
    counts = np.bincount(full.ravel(), minlength=17)
    # SPEC §3 character counts, after the mapping.
    assert counts[tiles.CHAR_TO_INDEX["X"]] == raw.count("X") == 8145
    assert counts[tiles.CHAR_TO_INDEX["t"]] == sum(raw.count(c) for c in "<>[]") == 1283
    assert counts[tiles.CHAR_TO_INDEX["*"]] == raw.count("B") + raw.count("b") == 49
    assert counts[tiles.CHAR_TO_INDEX["@"]] == raw.count("?") == 100
    assert counts[tiles.CHAR_TO_INDEX["-"]] == raw.count("-") + raw.count("x") + 2 * 7294
    windows = human_windows()
    assert windows.shape == (7294 - 56 + 1, 16, 56)
    assert (windows[5] == full[:, 5:61]).all()
