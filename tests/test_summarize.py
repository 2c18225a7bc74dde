"""``experiments/summarize.py`` on synthetic Tune experiment folders (params.json + result.json per trial)."""

import importlib.util
import json
import math
from pathlib import Path

import numpy as np
import pytest

SCRIPT = Path(__file__).resolve().parents[1] / "experiments" / "summarize.py"


@pytest.fixture(scope="module")
def summarize():
    spec = importlib.util.spec_from_file_location("summarize", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def write_trial(experiment: Path, *, variant: str, seed: int, qd_scores, evals, domain="maze", budget=None,
                done=True, repeat_from=None):
    """One trial folder as Tune writes it; ``repeat_from`` re-reports iterations as a crash restore does."""
    folder = experiment / f"DSAGETrainable_{variant}_{seed}"
    folder.mkdir(parents=True)
    params = {"domain": domain, "preset": "tiny", "variant": variant, "seed": seed}
    if budget is not None:
        params["budget"] = budget
    (folder / "params.json").write_text(json.dumps(params))
    rows = [{"training_iteration": i + 1, "evals": e, "qd_score": q, "coverage": q / 1000,
             "done": done and i == len(evals) - 1} for i, (e, q) in enumerate(zip(evals, qd_scores))]
    if repeat_from is not None:  # the stale first report of the repeated iterations comes first
        stale = [dict(r, qd_score=-1.0) for r in rows[repeat_from:]]
        rows = rows[:repeat_from] + stale + rows[repeat_from:]
    (folder / "result.json").write_text("\n".join(json.dumps(r) for r in rows) + "\n")


def maze_experiment(root: Path) -> Path:
    experiment = root / "ablation_maze_tiny"
    budget = 300  # each trial's budget (the tiny preset's is 150)
    evals = [100, 200, 300]
    write_trial(experiment, variant="map_elites", seed=0, qd_scores=[50, 80, 100], evals=evals, budget=budget)
    write_trial(experiment, variant="map_elites", seed=1, qd_scores=[60, 90, 120], evals=evals, budget=budget)
    # target = 110: dsage seed 0 reaches it at 200, seed 1 at 300; dr never (counts 300).
    write_trial(experiment, variant="dsage", seed=0, qd_scores=[50, 115, 150], evals=evals, budget=budget)
    write_trial(experiment, variant="dsage", seed=1, qd_scores=[50, 100, 130], evals=evals, budget=budget,
                repeat_from=1)
    write_trial(experiment, variant="dr", seed=0, qd_scores=[40, 60, 70], evals=evals, budget=budget)
    write_trial(experiment, variant="dr", seed=1, qd_scores=[45, 65, 75], evals=evals, budget=budget)
    return experiment


def rows(markdown: str) -> dict[str, list[str]]:
    lines = [line for line in markdown.splitlines() if line.startswith("| ")]
    return {cells[0]: cells[1:] for cells in ([c.strip() for c in line.strip("|").split("|")] for line in lines[1:])}


def test_maze_table_uses_the_papers_target_and_counts_never_as_the_budget(summarize, tmp_path, capsys):
    experiment = maze_experiment(tmp_path)
    assert summarize.main([str(experiment)]) == 0
    printed = capsys.readouterr().out
    header = printed.splitlines()[0]
    assert header == "| Variant | Runs | QD-score | Coverage (%) | Evaluations to QD-score 110.0 |"
    table = rows(printed)
    assert list(table) == ["dsage", "map_elites", "dr"]  # by final QD-score
    assert table["dsage"][:2] == ["2", "140.0 ± 10.0"]  # the restored trial's stale reports are dropped
    assert table["dsage"][3] == "250 ± 50"  # (200 + 300) / 2, s.e. 50
    # map_elites: seed 1 reaches 110 at 300, seed 0 never (counts its budget, 300).
    assert table["map_elites"][3] == "≥ 300 ± 0 (1/2 reached)"
    assert table["dr"][3] == "≥ 300 ± 0"
    assert "the mean final QD-score of map_elites over 2 runs" in printed
    assert (experiment / "summary.md").read_text().startswith(header)
    assert (experiment / "comparison.png").read_bytes()[:4] == b"\x89PNG"


def test_explicit_target_budget_from_the_config_and_unfinished_runs(summarize, tmp_path, capsys):
    experiment = tmp_path / "exp"
    # No budget key: the tiny preset's (150) comes from the config.
    write_trial(experiment, variant="dsage", seed=0, qd_scores=[5, 9], evals=[50, 100], done=False)
    write_trial(experiment, variant="dsage", seed=1, qd_scores=[5, 12], evals=[50, 100])
    out = tmp_path / "out"
    assert summarize.main([str(experiment), "--target", "10", "--out", str(out)]) == 0
    table = rows(capsys.readouterr().out)
    assert table["dsage"][0] == "2 (1 unfinished)"
    assert table["dsage"][3] == "≥ 125 ± 25 (1/2 reached)"  # (150 + 100) / 2
    assert (out / "summary.md").exists() and (out / "comparison.png").exists()


def test_mario_target_is_dsage_basic_and_a_missing_reference_is_one_error(summarize, tmp_path, capsys):
    mario = tmp_path / "mario"
    write_trial(mario, variant="dsage_basic", seed=0, qd_scores=[10, 20], evals=[100, 200], domain="mario", budget=200)
    write_trial(mario, variant="cma_me", seed=0, qd_scores=[30, 40], evals=[100, 200], domain="mario", budget=200)
    assert summarize.main([str(mario)]) == 0
    printed = capsys.readouterr().out
    assert "Evaluations to QD-score 20.0 |" in printed and "dsage_basic" in printed
    assert rows(printed)["cma_me"][3] == "100"  # one run: no standard error

    no_reference = tmp_path / "maze"
    write_trial(no_reference, variant="dsage", seed=0, qd_scores=[1, 2], evals=[100, 150])
    assert summarize.main([str(no_reference)]) == 2
    assert capsys.readouterr().err.strip() == (
        "summarize: no map_elites runs to set the default target (the paper's, for maze): pass --target")
    assert not (no_reference / "summary.md").exists()
    assert summarize.main([str(tmp_path / "empty")]) == 1


def test_mean_curve_is_a_step_function_of_evaluations_with_a_standard_error_band(summarize):
    runs = [{"evals": np.array([100.0, 200.0]), "qd_score": np.array([10.0, 30.0])},
            {"evals": np.array([150.0, 250.0]), "qd_score": np.array([20.0, 40.0])}]
    grid = np.array([0.0, 100.0, 150.0, 199.0, 250.0, 300.0])
    mean, se = summarize.mean_curve(runs, "qd_score", grid)
    np.testing.assert_allclose(mean, [0, 5, 15, 15, 35, 35])
    # Two runs: s.e. = |a − b| / 2.
    np.testing.assert_allclose(se, [0, 5, 5, 5, 5, 5])
    single_mean, single_se = summarize.mean_curve(runs[:1], "qd_score", grid)
    np.testing.assert_allclose(single_mean, [0, 10, 10, 10, 30, 30]) and not single_se.any()


def test_mean_se(summarize):
    assert summarize.mean_se([1.0, 3.0]) == (2.0, 1.0)
    mean, se = summarize.mean_se([4.0])
    assert mean == 4.0 and math.isnan(se)
    assert summarize.fmt(4.0, se, ".1f") == "4.0"
