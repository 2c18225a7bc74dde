import importlib.util
import sys
from pathlib import Path

import pytest

_BENCHMARKS = Path(__file__).resolve().parents[2] / "benchmarks"
sys.path.insert(0, str(_BENCHMARKS))  # the script imports metrics as its folder's module
_spec = importlib.util.spec_from_file_location("pool_audit_tables", _BENCHMARKS / "pool_audit_tables.py")
bench = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(bench)

HEAD = ("| Variant | Seed | Never solved | Cells with failure rate ≥ 0.5 | Worst return | Evaluations |\n"
        "|---|---|---|---|---|---|\n")


def _table(path: Path, rows: list[tuple[str, int, int, float]]) -> Path:
    body = "".join(f"| {arm} | {seed} | 0 | {cells:,} | {worst:,.0f} | 300 |\n" for arm, seed, cells, worst in rows)
    path.write_text("| Variant | Audits | ... |\n|---|---|---|\n| dsage | 2 | ... |\n\nPer audit:\n\n" + HEAD + body)
    return path


def test_two_tables_pool_into_one_mean_and_a_paired_difference_per_arm(tmp_path, capsys):
    first = _table(tmp_path / "a.md", [("dsage", 1, 60, -700), ("dr_t", 1, 30, -800)])
    second = _table(tmp_path / "b.md", [("dsage", 2, 80, -1_200), ("dr_t", 2, 40, -600)])
    assert bench.main([str(first), str(second)]) == 0
    out = capsys.readouterr().out
    assert "dsage                   70.0 ± 10.0  (2 seeds)" in out
    assert "dsage − dr_t +35.0 ± 5.0 paired (below 0 on 0 of 2 seeds); dsage 2.00× (per seed 2.00, 2.00)" in out
    assert "dsage − dr_t -250.0 ± 350.0 paired (below 0 on 1 of 2 seeds)" in out  # -1,200 parsed, not -1
    assert "dr_t" in out.split("worst return:")[1]


def test_a_seed_in_two_tables_and_a_file_without_per_audit_rows_are_refused(tmp_path, capsys):
    first = _table(tmp_path / "a.md", [("dsage", 1, 60, -700)])
    again = _table(tmp_path / "b.md", [("dsage", 1, 61, -710)])
    assert bench.main([str(first), str(again)]) == 2
    assert "dsage seed 1 is in another table too" in capsys.readouterr().err
    (tmp_path / "c.md").write_text("| Variant | Audits |\n|---|---|\n")
    assert bench.main([str(tmp_path / "c.md")]) == 2
    assert "no 'Per audit:' table" in capsys.readouterr().err
    (tmp_path / "d.md").write_text("Per audit:\n\n| Variant | Seed | Worst return |\n|---|---|---|\n| dsage | 3 | -5 |\n")
    assert bench.main([str(tmp_path / "d.md")]) == 2
    assert "no column 'Cells with failure rate ≥ 0.5'" in capsys.readouterr().err
    assert bench.main([str(first), "--reference", "map_elites"]) == 2
    assert "--reference 'map_elites' is not an arm" in capsys.readouterr().err
