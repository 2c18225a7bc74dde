"""benchmarks/bench_furthest_pairs.py: the bounded search against one BFS per empty cell, on a few mazes."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

BENCHMARKS = Path(__file__).resolve().parents[2] / "benchmarks"
sys.path.insert(0, str(BENCHMARKS))

import bench_furthest_pairs as bench  # noqa: E402


def test_it_times_both_on_the_same_mazes_and_checks_they_agree(capsys):
    speedups = bench.main(["--mazes", "40", "--seed", "3"])
    assert set(speedups) == {"random valid mazes", "their mutants (10 cells)"}
    assert all(s > 0 for s in speedups.values())
    out = capsys.readouterr().out
    assert out.count("same pairs: True") == 2


def test_a_search_that_found_other_pairs_stops_the_benchmark(monkeypatch):
    monkeypatch.setattr(bench, "furthest_pairs", lambda walls: bench._all_sources(~walls)[:, [1, 0, 2]])
    with pytest.raises(SystemExit, match="other pairs than the reference"):
        bench.main(["--mazes", "20"])
