import math

import numpy as np
import pandas as pd
from ribs.archives import ArchiveDataFrame

from dsage_ray.qd import archive_stats, archive_to_dataframe, make_archive
from tests.qd.helpers import DIM, OCC, bitmap_predict, checkpoint_round_trip


def _add(archive, solutions):
    objective, measures, extra = bitmap_predict(solutions)
    archive.add(solutions, objective, measures, **extra)


def test_make_archive_fields_and_dtypes(bitmap_archive):
    assert bitmap_archive.field_list == ["solution", "objective", "measures", "threshold", "occupancy", "index"]
    assert bitmap_archive.dtypes["solution"] == np.int8
    assert bitmap_archive.dtypes["occupancy"] == np.float32
    assert bitmap_archive.qd_score_offset == 0
    plain = make_archive(solution_dim=4, dims=(3,), ranges=[(0, 1)])
    assert "occupancy" not in plain.field_list and plain.dtypes["solution"] == np.float64


def test_archive_stats_empty_and_filled(bitmap_archive):
    empty = archive_stats(bitmap_archive)
    assert empty["qd_score"] == 0 and empty["coverage"] == 0 and empty["num_elites"] == 0
    assert math.isnan(empty["objective_mean"]) and math.isnan(empty["objective_max"])
    # Three elites in three different cells, objectives 0, 0.5, 1.
    solutions = np.zeros((3, DIM), dtype=np.int8)
    solutions[1, 0] = 1
    solutions[2, [0, -1]] = 1
    _add(bitmap_archive, solutions)
    stats = archive_stats(bitmap_archive)
    assert stats == {"qd_score": 1.5, "coverage": 3 / 128, "num_elites": 3, "num_cells": 128,
                     "objective_mean": 0.5, "objective_max": 1.0}


def test_qd_score_ignores_archive_offset():
    archive = make_archive(solution_dim=2, dims=(4,), ranges=[(0, 4)])
    archive._qd_score_offset = np.float64(-10.0)  # as if someone built it with an offset
    archive.add(np.zeros((2, 2)), [1.0, 2.0], [[0.5], [2.5]])
    assert archive_stats(archive)["qd_score"] == 3.0


def test_dataframe_without_and_with_flattened_occupancy(bitmap_archive):
    solutions = np.random.default_rng(0).integers(0, 2, size=(40, DIM))
    _add(bitmap_archive, solutions)
    df = archive_to_dataframe(bitmap_archive)
    assert isinstance(df, ArchiveDataFrame) and len(df) == len(bitmap_archive)
    assert list(df.columns) == ([f"solution_{i}" for i in range(DIM)] + ["objective", "measures_0", "measures_1",
                                "threshold", "index"])
    flat = archive_to_dataframe(bitmap_archive, flatten=True)
    assert isinstance(flat, ArchiveDataFrame)
    assert flat.columns[-1] == "index" and "occupancy_15" in flat.columns
    occupancy = flat.get_field("occupancy").reshape(-1, *OCC)
    np.testing.assert_array_equal(occupancy, bitmap_archive.data("occupancy"))
    np.testing.assert_array_equal(flat.get_field("solution"), bitmap_archive.data("solution"))
    # CSV round trip keeps pyribs' column convention.
    back = ArchiveDataFrame(pd.read_csv(pd.io.common.StringIO(flat.to_csv(index=False))))
    np.testing.assert_array_equal(back.get_field("index"), flat.get_field("index"))


def test_archive_checkpoint_round_trip_is_exact(bitmap_archive, tmp_path):
    _add(bitmap_archive, np.random.default_rng(0).integers(0, 2, size=(40, DIM)))
    restored = checkpoint_round_trip(bitmap_archive, tmp_path)
    for name in bitmap_archive.field_list:
        np.testing.assert_array_equal(restored.data(name), bitmap_archive.data(name))
    assert archive_stats(restored) == archive_stats(bitmap_archive)
    # The archive's RNG (used by sample_elites) continues identically.
    for _ in range(3):
        np.testing.assert_array_equal(restored.sample_elites(5)["index"], bitmap_archive.sample_elites(5)["index"])
