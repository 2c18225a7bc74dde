"""benchmarks/bench_symmetry.py: a level's start and goal move with its walls."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))

import bench_symmetry as bench  # noqa: E402


@pytest.mark.parametrize("name", list(bench.TRANSFORMS))
def test_a_cell_lands_where_the_transform_puts_its_value(name):
    transform = bench.TRANSFORMS[name]
    for cell in ((0, 0), (1, 3), (4, 2)):
        marked = np.zeros((5, 5), dtype=int)
        marked[cell] = 1
        assert transform(marked)[bench.moved_cell(transform, (5, 5), cell)] == 1


def test_the_transforms_are_the_eight_symmetries_of_the_square():
    square = np.arange(16).reshape(4, 4)
    images = {bench.TRANSFORMS[name](square).tobytes() for name in bench.TRANSFORMS}
    assert len(images) == 8
