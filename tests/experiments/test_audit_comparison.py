"""``experiments/audit_comparison.py``: audits per variant × seed, a table of their failure counts, resumable."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parents[2]


def load_script():
    spec = importlib.util.spec_from_file_location("audit_comparison", REPO_ROOT / "experiments" / "audit_comparison.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_two_searches_two_seeds_one_table_and_a_rerun_runs_nothing(tmp_path, capsys):
    from dsage_ray.audit.collection_file import load_collection
    from dsage_ray.audit.summary import failure_summary

    script = load_script()
    out = tmp_path / "cmp"
    argv = ["--agent", "builtin:random", "--preset", "tiny", "--variants", "dsage,dr", "--seeds", "2",
            "--budget", "24", "--set", "n_rand=24", "--set", "maze.episodes=3", "--out", str(out)]
    assert script.main(argv) == 0
    printed = capsys.readouterr().out
    assert "4 audits to run" in printed and printed.count(": done in ") == 4, printed
    table = (out / "summary.md").read_text()
    rows = {line.split("|")[1].strip(): line for line in table.splitlines()[2:] if line.startswith("| ")}
    assert set(rows) == {"dsage", "dr"}
    runs = json.loads((out / "summary.json").read_text())
    for variant in ("dsage", "dr"):
        collections = [load_collection(out / f"{variant}_seed{seed}" / "collection") for seed in (0, 1)]
        assert {c["config"]["variant"] for c in collections} == {variant}
        assert runs[variant] == [failure_summary(c) for c in collections]
        never = [failure_summary(c)["never_solved"] for c in collections]
        assert rows[variant].split("|")[3].strip().startswith(f"{sum(never) / 2:,.1f} ± ")
    # Everything collected: a second call only rebuilds the table.
    assert script.main(argv) == 0
    assert "0 audits to run" in capsys.readouterr().out
