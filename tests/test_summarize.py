"""``experiments/summarize.py`` on real Tune experiments whose trials report a scripted history.

A scripted trial stands in for a DSAGE run (seconds instead of minutes) but goes through Tune as
one does: its config and grid values, ``result.json``, and a crash restored from a checkpoint that
makes Tune re-report iterations.
"""

import importlib.util
import json
import os
from pathlib import Path

import numpy as np
import pytest
from ray import tune

SCRIPT = Path(__file__).resolve().parents[1] / "experiments" / "summarize.py"


@pytest.fixture(scope="module")
def summarize():
    spec = importlib.util.spec_from_file_location("summarize", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def script_key(config: dict) -> str:
    return json.dumps([config.get("variant"), config.get("seed"), config.get("selection.block")])


def trial(*, qd_scores, evals, wall_times=None, repeat_from=None, **grid_point):
    """``(script_key, script)``: one trial's history; ``repeat_from`` re-reports iterations as a crash restore does.
    Without ``wall_times`` the rows are those of a run from before ``wall_time`` was recorded."""
    rows = [{"evals": e, "qd_score": q, "coverage": q / 1000} for e, q in zip(evals, qd_scores)]
    for row, seconds in zip(rows, wall_times or ()):
        row["wall_time"] = seconds
    return script_key(grid_point), {"rows": rows, "repeat_from": repeat_from}


def run_experiment(root: Path, name: str, param_space: dict, scripts: dict) -> Path:
    """Runs a Tune experiment of :class:`ScriptedTrial` s; returns its folder."""
    trainable = tune.with_parameters(ScriptedTrial, scripts=scripts, marker_dir=str(root / f"{name}_markers"))
    (root / f"{name}_markers").mkdir(parents=True)
    # Trials reuse their actors (ScriptedTrial.reset_config): a process start costs more than a scripted trial.
    results = tune.Tuner(trainable, param_space=param_space, tune_config=tune.TuneConfig(reuse_actors=True),
                         run_config=tune.RunConfig(name=name, storage_path=str(root), verbose=0,
                                                   failure_config=tune.FailureConfig(max_failures=1))).fit()
    assert not results.errors
    return Path(results.experiment_path)


class ScriptedTrial(tune.Trainable):
    """Reports its script's rows, one per step. With ``repeat_from``, the first attempt reports
    the rows from there on with a stale QD-score of -1, checkpointed only at ``repeat_from``, then
    crashes; Tune restores it from that checkpoint and it reports the true rows."""

    def setup(self, config, scripts, marker_dir):
        self.scripts, self.marker_dir = scripts, Path(marker_dir)
        self.reset_config(config)

    def reset_config(self, new_config):
        script = self.scripts[script_key(new_config)]
        self.rows, self.repeat_from = script["rows"], script["repeat_from"]
        self.marker = self.marker_dir / "".join(c if c.isalnum() else "_" for c in script_key(new_config))
        self.row = 0
        return True

    def step(self):
        stale = self.repeat_from is not None and not self.marker.exists()
        if stale and self.row == len(self.rows):
            self.marker.touch()
            raise RuntimeError("scripted crash")
        result = dict(self.rows[self.row])
        if stale and self.row >= self.repeat_from:
            result["qd_score"] = -1.0
        self.row += 1
        result["done"] = self.row == len(self.rows) and not stale
        result["should_checkpoint"] = self.row == self.repeat_from
        return result

    def save_checkpoint(self, checkpoint_dir):
        Path(checkpoint_dir, "row").write_text(str(self.row))

    def load_checkpoint(self, checkpoint):
        self.row = int(Path(checkpoint, "row").read_text())


def maze_experiment(root: Path) -> Path:
    evals = [100, 200, 300]
    scripts = dict([
        trial(variant="map_elites", seed=0, qd_scores=[50, 80, 100], evals=evals),
        trial(variant="map_elites", seed=1, qd_scores=[60, 90, 120], evals=evals),
        # target = 110: dsage seed 0 reaches it at 200, seed 1 at 300; dr never (counts 300).
        trial(variant="dsage", seed=0, qd_scores=[50, 115, 150], evals=evals),
        trial(variant="dsage", seed=1, qd_scores=[50, 100, 130], evals=evals, repeat_from=1),
        trial(variant="dr", seed=0, qd_scores=[40, 60, 70], evals=evals),
        trial(variant="dr", seed=1, qd_scores=[45, 65, 75], evals=evals),
    ])
    # Each trial's budget is 300 (the tiny preset's is 150).
    space = {"domain": "maze", "preset": "tiny", "budget": 300,
             "variant": tune.grid_search(["map_elites", "dsage", "dr"]), "seed": tune.grid_search([0, 1])}
    return run_experiment(root, "ablation_maze_tiny", space, scripts)


@pytest.fixture(scope="module")
def maze_tune(ray_session, tmp_path_factory) -> Path:
    """One :func:`maze_experiment` for the tests that read it (a Tune experiment costs seconds)."""
    return maze_experiment(tmp_path_factory.mktemp("maze"))


def rows(markdown: str) -> dict[str, list[str]]:
    lines = [line for line in markdown.splitlines() if line.startswith("| ")]
    return {cells[0]: cells[1:] for cells in ([c.strip() for c in line.strip("|").split("|")] for line in lines[1:])}


def test_maze_table_uses_the_papers_target_and_counts_never_as_the_budget(summarize, maze_tune, capsys):
    experiment = maze_tune
    stale = [json.loads(line)["qd_score"] for result in experiment.glob("*seed=1*variant=dsage*/result.json")
             for line in result.read_text().splitlines()]
    assert -1.0 in stale, "no iteration was re-reported: the restore case is not exercised"
    capsys.readouterr()
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


def test_explicit_target_budget_from_the_config_and_unfinished_runs(summarize, ray_session, tmp_path, capsys):
    # No budget key: the tiny preset's (150) comes from the config; seed 0 stops short of it.
    scripts = dict([trial(variant="dsage", seed=0, qd_scores=[5, 9], evals=[50, 100]),
                    trial(variant="dsage", seed=1, qd_scores=[12, 13], evals=[50, 150])])
    space = {"domain": "maze", "preset": "tiny", "variant": "dsage", "seed": tune.grid_search([0, 1])}
    experiment = run_experiment(tmp_path, "exp", space, scripts)
    out = tmp_path / "out"
    capsys.readouterr()
    assert summarize.main([str(experiment), "--target", "10", "--out", str(out)]) == 0
    table = rows(capsys.readouterr().out)
    assert table["dsage"][0] == "2 (1 unfinished)"
    assert table["dsage"][3] == "≥ 100 ± 50 (1/2 reached)"  # (150 + 50) / 2
    assert (out / "summary.md").exists() and (out / "comparison.png").exists()


def test_a_row_per_value_of_every_grid_key(summarize, ray_session, tmp_path, capsys, monkeypatch):
    blocks = [[4, 3], [8, 6]]
    scripts = dict(trial(variant=variant, seed=seed, **{"selection.block": block}, evals=[100, 200],
                         qd_scores=[10, 10 * (i + 1) + seed + (5 if variant == "dsage" else 0)])
                   for variant in ("dsage", "map_elites") for i, block in enumerate(blocks) for seed in (0, 1))
    space = {"domain": "maze", "preset": "tiny", "budget": 200, "variant": tune.grid_search(["dsage", "map_elites"]),
             "selection.block": tune.grid_search(blocks), "seed": tune.grid_search([0, 1])}
    experiment = run_experiment(tmp_path, "grid", space, scripts)
    capsys.readouterr()
    # A relative folder, as a user types it (Tune reads a relative path as a URI without a scheme).
    monkeypatch.chdir(tmp_path)
    assert summarize.main([str(experiment.relative_to(tmp_path))]) == 0
    printed = capsys.readouterr().out
    lines = [line for line in printed.splitlines() if line.startswith("| ")]
    assert lines[0].startswith("| Variant | selection.block | Runs | QD-score |")
    cells = [[c.strip() for c in line.strip("|").split("|")] for line in lines[1:]]
    # Sorted by final QD-score; seeds 0 and 1 averaged in each of the 4 groups.
    assert [row[:4] for row in cells] == [
        ["dsage", "[8, 6]", "2", "25.5 ± 0.5"], ["map_elites", "[8, 6]", "2", "20.5 ± 0.5"],
        ["dsage", "[4, 3]", "2", "15.5 ± 0.5"], ["map_elites", "[4, 3]", "2", "10.5 ± 0.5"]]
    # The target pools every map_elites run: (10.5 + 20.5) / 2.
    assert "Evaluations to QD-score 15.5 |" in lines[0]


def test_mario_target_is_dsage_basic_and_without_a_reference_the_table_has_no_target_column(
        summarize, ray_session, tmp_path, capsys):
    scripts = dict([trial(variant="dsage_basic", seed=0, qd_scores=[10, 20], evals=[100, 200]),
                    trial(variant="cma_me", seed=0, qd_scores=[30, 40], evals=[100, 200])])
    space = {"domain": "mario", "preset": "tiny", "budget": 200, "seed": 0,
             "variant": tune.grid_search(["dsage_basic", "cma_me"])}
    mario = run_experiment(tmp_path, "mario", space, scripts)
    capsys.readouterr()
    assert summarize.main([str(mario)]) == 0
    printed = capsys.readouterr().out
    assert "Evaluations to QD-score 20.0 |" in printed and "dsage_basic" in printed
    assert rows(printed)["cma_me"][3] == "100"  # one run: no standard error

    # A grid of DSAGE alone (issue 20): no map_elites run sets the target, so the table goes without that column.
    scripts = dict([trial(variant="dsage", seed=0, qd_scores=[1, 2], evals=[100, 150])])
    no_reference = run_experiment(tmp_path, "maze", {"domain": "maze", "preset": "tiny", "variant": "dsage",
                                                     "seed": 0}, scripts)
    capsys.readouterr()
    assert summarize.main([str(no_reference)]) == 0
    printed = capsys.readouterr().out
    assert printed.splitlines()[0] == "| Variant | Runs | QD-score | Coverage (%) |"
    assert rows(printed)["dsage"] == ["1", "2.0", "0.20"]
    assert ("No evaluations-to-target column: no map_elites runs to set the default target (the paper's, for "
            "maze): pass --target." in printed)
    # Rows from before wall_time was recorded: one line instead of the equal-time table.
    assert "No equal-time table: some runs' rows carry no wall_time" in printed and "At equal wall time" not in printed
    assert (no_reference / "summary.md").exists()
    assert summarize.main([str(tmp_path / "empty")]) == 1
    assert capsys.readouterr().err.strip() == f"summarize: no Tune experiment under {tmp_path / 'empty'}"


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


def test_rows_from_two_experiments_with_a_variant_filter(summarize, maze_tune, tmp_path, capsys):
    old = maze_tune
    evals = [100, 200, 300]
    scripts = dict([trial(variant="dsage", seed=0, qd_scores=[60, 150, 200], evals=evals),
                    trial(variant="dsage", seed=1, qd_scores=[60, 160, 220], evals=evals)])
    space = {"domain": "maze", "preset": "tiny", "budget": 300, "variant": "dsage", "seed": tune.grid_search([0, 1])}
    new = run_experiment(tmp_path / "new", "rerun", space, scripts)
    out = tmp_path / "out"
    capsys.readouterr()
    assert summarize.main([str(new), f"{old}:map_elites,dr", "--out", str(out)]) == 0
    table = rows(capsys.readouterr().out)
    assert list(table) == ["dsage", "map_elites", "dr"]
    assert table["dsage"][:2] == ["2", "210.0 ± 10.0"]  # the re-run's, not the old experiment's 140
    assert table["map_elites"][1] == "110.0 ± 10.0"
    # Without the filter dsage would come from both: refused, nothing written.
    assert summarize.main([str(new), str(old), "--out", str(tmp_path / "mixed")]) == 1
    assert "variant dsage has trials in both" in capsys.readouterr().err
    assert not (tmp_path / "mixed").exists()
    assert summarize.main([str(new), f"{old}:dsage_basic"]) == 1
    assert "has no trials of dsage_basic" in capsys.readouterr().err


def test_equal_time_table_reads_each_run_at_the_shortest_runs_final_wall_time(summarize, ray_session, tmp_path,
                                                                             capsys):
    evals = [100, 200, 300]
    scripts = dict([
        # MAP-Elites is fast: its seed 0 ends first, at 30 s, which sets the common time.
        trial(variant="map_elites", seed=0, qd_scores=[50, 80, 100], evals=evals, wall_times=[10, 20, 30]),
        trial(variant="map_elites", seed=1, qd_scores=[60, 90, 120], evals=evals, wall_times=[12, 24, 36]),
        # DSAGE is ahead per evaluation but slow: at 30 s seed 0 has ended one iteration (50), seed 1 two (100).
        trial(variant="dsage", seed=0, qd_scores=[50, 115, 150], evals=evals, wall_times=[25, 50, 75]),
        trial(variant="dsage", seed=1, qd_scores=[50, 100, 130], evals=evals, wall_times=[10, 30, 60]),
    ])
    space = {"domain": "maze", "preset": "tiny", "budget": 300,
             "variant": tune.grid_search(["map_elites", "dsage"]), "seed": tune.grid_search([0, 1])}
    experiment = run_experiment(tmp_path, "timed", space, scripts)
    capsys.readouterr()
    assert summarize.main([str(experiment)]) == 0
    printed = capsys.readouterr().out
    per_evaluation, _, timed = printed.partition("At equal wall time (30 s")
    assert list(rows(per_evaluation)) == ["dsage", "map_elites"]  # by final QD-score
    assert timed, "no equal-time table"
    header = next(line for line in timed.splitlines() if line.startswith("| "))
    assert header == "| Variant | Runs | QD-score at 30 s | Coverage (%) | Evaluations | Full run (s) |"
    table = rows(timed)
    assert list(table) == ["map_elites", "dsage"]  # at equal time the order turns
    assert table["map_elites"] == ["2", "95.0 ± 5.0", "9.50 ± 0.50", "250 ± 50", "33 ± 3"]  # (100 + 90) / 2
    assert table["dsage"] == ["2", "75.0 ± 25.0", "7.50 ± 2.50", "150 ± 50", "68 ± 8"]  # (50 + 100) / 2
    from PIL import Image

    with Image.open(experiment / "comparison.png") as image:
        assert image.size == (1100, 800)  # the wall-time panels under the evaluation ones


def test_values_at_reads_a_step_function_on_either_axis(summarize):
    run = {"evals": np.array([100.0, 200.0]), "wall_time": np.array([4.0, 9.5]), "qd_score": np.array([10.0, 30.0])}
    at = np.array([0.0, 3.9, 4.0, 9.4, 9.5, 20.0])
    np.testing.assert_allclose(summarize.values_at([run], "qd_score", at, x="wall_time")[0], [0, 0, 10, 10, 30, 30])
    np.testing.assert_allclose(summarize.values_at([run], "evals", at, x="wall_time")[0], [0, 0, 100, 100, 200, 200])
    assert summarize.common_wall_time([run, {**run, "wall_time": np.array([2.0, 7.0])}]) == 7.0
    assert summarize.common_wall_time([run, {**run, "wall_time": None}]) is None
