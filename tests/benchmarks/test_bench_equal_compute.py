"""benchmarks/bench_equal_compute.py: the step-function readings and the pairing by seed at a run's own end."""

from __future__ import annotations

import json
import sys
from pathlib import Path

BENCHMARKS = Path(__file__).resolve().parents[2] / "benchmarks"
sys.path.insert(0, str(BENCHMARKS))

import bench_equal_compute as bench  # noqa: E402


def run(seed: int, rows: list[tuple[int, float, float, float]], variant: str) -> dict:
    """A loaded run on a quiet machine: rows of (evals, qd_score, cpu_time at the row's end, time_evaluate of the
    row); the row's time_total is its span on the clock."""
    ends = [t for _, _, t, _ in rows]
    spans = [end - start for start, end in zip([0.0, *ends], ends)]
    history = [{"evals": e, "qd_score": q, "cpu_time": t, "wall_time": t, "time_evaluate": ev, "time_total": span}
               for (e, q, t, ev), span in zip(rows, spans)]
    return {"folder": Path("."), "variant": variant, "name": variant, "seed": seed, "history": history}


# A surrogate run with two long outer iterations, and a baseline with short batches.
SURROGATE = run(1, [(100, 50.0, 100.0, 40.0), (400, 300.0, 500.0, 200.0)], "dsage")
BASELINE = run(1, [(150 * k, 40.0 * k, 60.0 * k, 60.0) for k in range(1, 11)], "map_elites")


def test_a_common_horizon_reads_the_surrogate_run_before_its_last_step():
    assert bench.qd_at_time(SURROGATE["history"], 499.0, "cpu") == 50.0
    assert bench.qd_at_time(SURROGATE["history"], 500.0, "cpu") == 300.0
    assert bench.qd_at_time(BASELINE["history"], 499.0, "cpu") == 320.0  # 8 batches ended by 480 s


def test_pairs_read_the_baseline_where_each_run_ended():
    (seed, own, base, long_enough), = bench.paired_at_own_end([SURROGATE], [BASELINE], "cpu")
    assert (seed, own, base, long_enough) == (1, 300.0, 320.0, True)  # 8 batches by 500 s


def test_surrogate_free_pairs_count_evaluation_seconds_only():
    # The surrogate run evaluated for 240 s; the baseline had 4 batches (240 s of evaluation) by then.
    (_, own, base, _), = bench.paired_at_own_end([SURROGATE], [BASELINE], "cpu", evaluation_only=True)
    assert (own, base) == (300.0, 160.0)


def test_a_baseline_that_stopped_early_is_flagged_and_seeds_without_a_partner_are_skipped():
    short = run(1, [(150, 40.0, 60.0, 60.0)], "map_elites")
    (_, _, base, long_enough), = bench.paired_at_own_end([SURROGATE], [short], "cpu")
    assert (base, long_enough) == (40.0, False)
    assert bench.paired_at_own_end([run(2, [(1, 1.0, 1.0, 1.0)], "dsage")], [BASELINE], "cpu") == []


def test_a_budget_reads_the_run_where_the_iteration_that_reached_it_ended():
    # 250 evaluations were reached by the second iteration (400), which ended at 500 s: 8 baseline batches.
    assert bench.paired_at_own_end([SURROGATE], [BASELINE], "cpu", at_evals=250) == [(1, 300.0, 320.0, True)]
    # 100 exactly: the first iteration, ended at 100 s, when the baseline had one batch.
    assert bench.paired_at_own_end([SURROGATE], [BASELINE], "cpu", at_evals=100) == [(1, 50.0, 40.0, True)]
    assert bench.paired_at_own_end([SURROGATE], [BASELINE], "cpu", at_evals=401) == []


def test_the_length_table_has_a_row_per_budget(capsys):
    bench.print_by_length("dsage", "map_elites", [SURROGATE], [BASELINE], "cpu", [100, 400, 401])
    rows = [line for line in capsys.readouterr().out.splitlines() if line.startswith("| ") and "---" not in line]
    # 100 evaluations: 50 against the baseline's 100/150 · 40 per evaluation, and 50 against 40 at 100 s.
    assert rows[1] == "| 100 | 1 | 50.0 | 1.88x | 1.25x |"
    assert rows[2] == "| 400 | 1 | 300.0 | 2.81x | 0.94x |"
    assert rows[3] == "| 401 | 0 | no dsage run reached it | | |"


def test_the_length_table_flags_a_baseline_that_made_fewer_evaluations_or_stopped_sooner(capsys):
    short = run(1, [(150, 40.0, 60.0, 60.0)], "map_elites")
    bench.print_by_length("dsage", "map_elites", [SURROGATE], [short], "cpu", [400])
    row = [line for line in capsys.readouterr().out.splitlines() if line.startswith("| 400")][0]
    assert "(1 map_elites run(s) made fewer evaluations)" in row and "(1 map_elites run(s) stopped before" in row


def test_main_prints_the_paired_ratio(tmp_path, capsys):
    for loaded in (SURROGATE, BASELINE):
        folder = tmp_path / loaded["variant"]
        folder.mkdir()
        (folder / "config.json").write_text(json.dumps({"variant": loaded["variant"], "seed": loaded["seed"]}))
        history = [{**row, "time_exploit": 1.0} if loaded is SURROGATE else row for row in loaded["history"]]
        (folder / "metrics.json").write_text(json.dumps(history))
    assert bench.main([str(tmp_path / "dsage"), str(tmp_path / "map_elites"), "--clock", "cpu"]) == 0
    out = capsys.readouterr().out
    assert "seed 1: 300.0 vs 320.0 → 0.94x" in out
    assert "dsage / map_elites at each dsage run's own end (cpu time): 0.94x over 1 seeds (dsage 300.0 vs map_elites 320.0)" in out


def test_time_to_reach_is_the_end_of_the_first_step_at_or_above_the_target():
    assert bench.time_to_reach(BASELINE["history"], 300.0, "cpu") == 480.0  # 8 batches: 320
    assert bench.time_to_reach(BASELINE["history"], 401.0, "cpu") is None


def test_the_counting_bound_allows_one_new_elite_per_evaluation():
    # 400 evaluations, 300 elites of objective 2 (QD 600), ended at 500 s, half of its time evaluating.
    history = [{"evals": 400, "qd_score": 600.0, "num_elites": 300, "cpu_time": 500.0, "wall_time": 500.0,
                "time_evaluate": 100.0, "time_total": 200.0}]
    surrogate = {"seed": 1, "history": history}
    bound = bench.counting_bound(surrogate, BASELINE, "cpu")  # the baseline has 320 by 500 s
    assert bound["baseline_qd"] == 320.0 and bound["ratio"] == 600.0 / 320.0
    assert bound["yield"] == 0.75
    assert bound["perfect"] == 400 * 2.0 / 320.0
    # 0.625 evaluation seconds per level: 800 evaluations in 500 s with the surrogate free.
    assert bound["perfect_free"] == 800 * 2.0 / 320.0


def test_evaluation_seconds_follow_the_chosen_clock_on_a_shared_machine():
    # Neighbours doubled the wall clock: 100 s of wall per row (60 evaluating) for 50 s of CPU.
    history = [{"evals": 10 * k, "qd_score": float(k), "cpu_time": 50.0 * k, "wall_time": 100.0 * k,
                "time_evaluate": 60.0, "time_total": 100.0} for k in (1, 2)]
    assert list(bench.evaluation_ends(history, "cpu")) == [30.0, 60.0]
    assert list(bench.evaluation_ends(history, "wall")) == [60.0, 120.0]
    assert bench.evals_and_time_to(history, 1.5, "cpu") == (15.0, 45.0)


def test_the_selected_batch_error_is_the_median_from_outer_iteration_three_per_measure():
    rows = [{"outer_iteration": 1}, {"outer_iteration": 2, "mae_path": 500.0},
            {"outer_iteration": 3, "mae_path": 90.0, "mae_walls": 4.0, "mae_objective": 1.0, "mae_occupancy": 2.0},
            {"outer_iteration": 4, "mae_path": 30.0, "mae_walls": 6.0},
            {"outer_iteration": 5, "mae_path": 60.0, "mae_walls": None}]
    errors = bench.selected_batch_errors({"history": rows})
    # Iteration 2's batch (the first picks, from a model trained on random levels) is left out, as are the
    # objective and the occupancy, which are not measures.
    assert errors == {"path": 60.0, "walls": 5.0}
    assert bench.selected_batch_errors({"history": rows[:2]}) == {}


def test_a_pipelined_rows_evaluate_is_only_the_wait_beyond_the_overlapped_surrogate():
    # 30 s of batch, of which the driver trained and exploited for 20 s while it ran: 10 s of waiting.
    history = [{"evals": 100, "qd_score": 1.0, "cpu_time": 30.0, "wall_time": 30.0, "time_train": 5.0,
                "time_exploit": 15.0, "time_overlapped": 20.0, "time_evaluate": 30.0, "time_total": 30.0}]
    (row,) = bench.phase_seconds(history, "wall")
    assert row["evaluate"] == 10.0 and row["train"] + row["exploit"] == 20.0
    assert sum(row[phase] for phase in bench.PHASES) == row["total"]


def test_realized_over_expected_reads_every_iteration_but_the_last():
    gain = run(2, [(100, 90.0, 10.0, 5.0), (300, 250.0, 40.0, 20.0), (500, 350.0, 70.0, 20.0),
                   (520, 360.0, 75.0, 2.0)], "dsage_gain")
    for row, expected in zip(gain["history"], [None, 200.0, 125.0, 50.0]):
        if expected is not None:
            row["selection_expected_gain"] = expected
    # (250 - 90) + (350 - 250) added against 200 + 125 expected; the last, budget-cut iteration is left out.
    assert bench.realized_over_expected(gain) == 260.0 / 325.0
    assert bench.realized_over_expected(SURROGATE) is None


def test_a_screened_runs_screens_are_counted_as_evaluations_in_their_own_reading(capsys):
    screened = run(1, [(100, 50.0, 100.0, 40.0), (400, 300.0, 500.0, 200.0)], "scr")
    for row, count in zip(screened["history"], (0.0, 1500.0)):
        row["selection_screened"] = count
    screened["screen_share"] = 1 / 50  # one episode of a 50-episode evaluation
    bench.print_screen_equivalents("scr", "map_elites", [screened], [BASELINE], 400)
    printed = capsys.readouterr().out
    # 1,500 screened levels by 400 evaluations = 30 evaluations' episodes: the baseline is read at 430 (40 × 430/150).
    assert "seed 1: its screens cost 30 evaluations' episodes by 400 evaluations; 300.0 vs map_elites 114.7 at 430" \
        in printed, printed
    assert "scr / map_elites at equal evaluations, its screens counted as evaluations: 2.62x over 1 seeds" in printed


def test_the_screen_share_comes_from_a_nested_or_a_flat_config(tmp_path):
    for name, config in (("config.json", {"variant": "dsage", "domain": "maze", "maze": {"episodes": 50},
                                          "selection": {"screen_episodes": 2}}),
                         ("params.json", {"variant": "dsage", "maze.episodes": 50, "selection.screen_episodes": 2})):
        folder = tmp_path / name.split(".")[0]
        folder.mkdir()
        (folder / name).write_text(json.dumps(config))
        (folder / "metrics.json").write_text(json.dumps([{"evals": 1, "qd_score": 1.0, "time_total": 1.0}]))
        assert bench.load_run(folder)["screen_share"] == 2 / 50


def test_the_coverage_at_equal_time_is_read_like_the_qd_score(tmp_path, capsys):
    for loaded, coverages in ((SURROGATE, [0.01, 0.04]), (BASELINE, [0.002 * k for k in range(1, 11)])):
        folder = tmp_path / loaded["variant"]
        folder.mkdir()
        (folder / "config.json").write_text(json.dumps({"variant": loaded["variant"], "seed": loaded["seed"]}))
        history = [{**row, "coverage": c} for row, c in zip(loaded["history"], coverages)]
        (folder / "metrics.json").write_text(json.dumps(history))
    assert bench.main([str(tmp_path / "dsage"), str(tmp_path / "map_elites"), "--clock", "cpu", "--at-time",
                       "450", "--at-evals", "400"]) == 0
    out = capsys.readouterr().out
    # By 450 s the surrogate run had ended only its first iteration; the baseline its 7th batch.
    assert "| dsage | 1 | 300.0 | 50.0 | 1.00% | 100 |" in out
    assert "| map_elites | 1 | 106.7 | 280.0 | 1.40% | 1,050 |" in out
