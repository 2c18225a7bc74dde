import importlib.util
import json
from pathlib import Path

import numpy as np

_PATH = Path(__file__).resolve().parents[2] / "benchmarks" / "gym_failure_by_parameter.py"
_spec = importlib.util.spec_from_file_location("gym_failure_by_parameter", _PATH)
bench = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(bench)


def test_predicted_share_is_high_when_failure_follows_the_parameters_and_near_zero_when_it_does_not():
    rng = np.random.default_rng(0)
    values = rng.uniform([0.0, -12.0], [2.0, -2.0], size=(400, 2))  # two parameters on different scales
    follows = (values[:, 0] > 1.0).astype(float)  # fails exactly where the first parameter is high
    assert bench.predicted_share(values, follows) > 0.8
    luck = rng.binomial(10, 0.3, size=400) / 10  # the same failure chance everywhere
    assert bench.predicted_share(values, luck) < 0.1


def test_the_table_ends_with_the_predicted_share(tmp_path, capsys):
    rng = np.random.default_rng(1)
    levels = [{"param.a": float(a), "param.b": float(b), "objective": float(a > 0.5)}
              for a, b in rng.uniform(size=(60, 2))]
    for level in levels:
        level["measures"] = {"param.a": level["param.a"], "param.b": level["param.b"]}
    archive = {"measures": ["param.a", "param.b"], "measure_ranges": [[0, 1], [0, 1]], "archive_dims": [2, 2]}
    (tmp_path / "collection.json").write_text(json.dumps({"levels": levels, **archive}))
    bench.main([str(tmp_path)])
    out = capsys.readouterr().out
    assert out.startswith("60 levels from 1 collections")
    assert "| param.a |" in out and "| param.b |" in out
    share = float(out.strip().splitlines()[-2].rsplit(" ", 1)[1])
    assert share > 0.5
    # Two of the four cells have a > 0.5, where every level fails.
    assert out.strip().splitlines()[-1] == ("archive cells: 4 of 4 hold a level; of the 4 with 3 levels or more, 2 fail "
                                            "at least half of their levels' episodes on average; 2 hold a level that "
                                            "failed at least half of its own")


def test_cells_pool_the_levels_of_every_collection_and_a_lucky_level_counts_its_cell(tmp_path):
    archive = {"measures": ["param.a"], "measure_ranges": [[0, 1]], "archive_dims": [2]}
    for name, rates in (("one", [0.6, 0.0]), ("two", [0.2, 0.1])):
        levels = [{"measures": {"param.a": at}, "objective": rate} for at, rate in zip((0.2, 0.9), rates)]
        (tmp_path / name).mkdir()
        (tmp_path / name / "collection.json").write_text(json.dumps({"levels": levels, **archive}))
    total, cells = bench.cell_failure([tmp_path / "one", tmp_path / "two"])
    assert total == 2 and cells == {(0,): [0.6, 0.2], (1,): [0.0, 0.1]}
