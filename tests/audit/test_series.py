"""An audit series on tiny in-process audits: the suite grows, fixed/regressed, resume, a failing checkpoint, the
report, TensorBoard and ``dsage-ray audit-series`` (issue 19 item 2)."""

from __future__ import annotations

import contextlib
import io
import json
import logging
import os
import re
import shutil
import time
from pathlib import Path

import numpy as np
import pytest

from dsage_ray.audit.results import Collection
from dsage_ray.audit.series import (SERIES_FILE, SERIES_REPORT, AuditSeries, SeriesRecord, default_budget,
                                    fixed_and_regressed, is_failing)
from dsage_ray.cli import main


#: One outer iteration of 6 random 8x8 mazes, 4 episodes per level: a few seconds per checkpoint.
TINY = {"n_rand": 6, "image_every": 0, "maze.height": 8, "maze.width": 8}
SETTINGS = dict(preset="tiny", budget=6, episodes=4, overrides=TINY, local=True)
#: The same on the command line.
TINY_ARGS = ["--preset", "tiny", "--budget", "6", "--episodes", "4", "--local",
             *(arg for key, value in TINY.items() for arg in ("--set", f"{key}={value}"))]
CHECKPOINTS = ["builtin:random", "builtin:nope", "builtin:wall_follower"]


@pytest.fixture(scope="module")
def series(tmp_path_factory) -> AuditSeries:
    """Three checkpoints: the random agent (many failures), one that does not load, the wall follower."""
    out = tmp_path_factory.mktemp("series") / "s"
    series = AuditSeries(out_dir=out, warm_start=False, **SETTINGS)
    for agent in CHECKPOINTS:
        series.audit(agent, step=1000 * (len(series.records) + 1))
    return series


def test_the_series_records_every_checkpoint_and_the_suite_grows(series):
    data = json.loads((series.out_dir / SERIES_FILE).read_text())
    assert [r["agent"] for r in data["records"]] == CHECKPOINTS and data["domain"] == "maze"
    first, broken, last = series.records
    assert first.error is None and first.suite_size == 0 and first.suite_success_rate is None
    assert first.new_failures > 0 and first.summary["levels"] >= first.new_failures
    assert first.new_failures == sum(level.origin == 0 for level in series.suite)
    # The suite re-evaluated on the wall follower is everything the random agent's audit found.
    assert last.error is None and last.suite_size == first.new_failures == len(series.suite) - last.new_failures
    assert last.suite_success_rate == pytest.approx(np.mean([lv.results[2] for lv in series.suite if lv.origin < 2]))
    assert [r.step for r in series.records] == [1000, 2000, 3000]
    # Suite levels are distinct, failing when found, with the seed their collection recorded.
    assert len({lv.solution.tobytes() for lv in series.suite}) == len(series.suite)
    collection = Collection.load(Path(first.audit_dir) / "collection")
    seeds = {lv.level_path.resolve(): lv.seed for lv in collection.levels}
    for level in (lv for lv in series.suite if lv.origin == 0):
        assert is_failing(level.results[0])
        assert seeds[(series.out_dir / level.level_file).resolve()] == level.seed


def test_a_checkpoint_that_does_not_load_is_recorded_and_the_series_goes_on(series):
    broken = series.records[1]
    assert broken.error.startswith("agent 'builtin:nope'") and "\n" not in broken.error
    assert (broken.suite_size, broken.fixed, broken.regressed, broken.new_failures, broken.summary,
            broken.audit_dir) == (0, (), (), 0, {}, None)
    # No suite number at the broken checkpoint: the next one compares with the last result measured (#0).
    assert all(1 not in lv.results for lv in series.suite)
    fixed, regressed = fixed_and_regressed({lv.id: lv.results[0] for lv in series.suite if lv.origin == 0},
                                           {lv.id: lv.results[2] for lv in series.suite if lv.origin == 0})
    assert (series.records[2].fixed, series.records[2].regressed) == (fixed, regressed)
    assert series.records[2].fixed, "the wall follower solves some of the random agent's failures"


def test_fixed_and_regressed_on_a_constructed_case():
    assert is_failing(0.0) and is_failing(0.5) and not is_failing(0.6) and not is_failing(1.0)
    previous = {0: 0.0, 1: 1.0, 2: 0.5, 3: 0.6, 4: 0.2, 6: 0.9}
    current = {0: 1.0, 1: 0.0, 2: 0.6, 3: 0.5, 5: 0.0, 6: 0.8}
    assert fixed_and_regressed(previous, current) == ((0, 2), (1, 3))  # 4 and 5 are not measured twice


def test_the_default_budget_is_a_quarter_of_the_preset_and_one_iteration_at_least():
    from dsage_ray.audit.collection import audit_config

    assert default_budget(audit_config(preset="cpu")) == 1000
    assert default_budget(audit_config(preset="tiny")) == 70  # n_rand 50 + selection.count 20 > 150 / 4
    assert AuditSeries(out_dir="/nonexistent/never/written", preset="demo").budget == 150


def test_a_rerun_continues_the_series_and_skips_what_is_recorded(series, monkeypatch):
    import dsage_ray.audit.series as module

    monkeypatch.setattr(module, "run_audit", lambda **kwargs: pytest.fail("a recorded checkpoint was audited again"))
    again = AuditSeries(out_dir=series.out_dir, warm_start=False, **SETTINGS)
    assert again.records == series.records
    assert [(lv.id, lv.seed, lv.results, lv.solution.tobytes()) for lv in again.suite] == \
        [(lv.id, lv.seed, lv.results, lv.solution.tobytes()) for lv in series.suite]
    before = (series.out_dir / SERIES_FILE).stat().st_mtime_ns
    assert again.audit("builtin:wall_follower") == series.records[2]
    assert len(again.records) == 3 and (series.out_dir / SERIES_FILE).stat().st_mtime_ns == before
    with pytest.raises(ValueError, match="series of domain 'maze', not 'mario'"):
        AuditSeries(out_dir=series.out_dir, domain="mario")


def test_a_failing_search_is_one_warning_keeps_the_suite_numbers_and_warm_starts_from_the_last_audit(
        series, tmp_path, monkeypatch, caplog):
    """On a copy of the series: the next checkpoint's search raises; its suite numbers are kept."""
    import dsage_ray.audit.series as module

    copy = tmp_path / "copy"
    shutil.copytree(series.out_dir, copy)
    seen = {}

    def failing_audit(**kwargs):
        seen.update(kwargs)
        raise RuntimeError("simulator actor died\nwith a traceback")

    monkeypatch.setattr(module, "run_audit", failing_audit)
    continued = AuditSeries(out_dir=copy, **SETTINGS)  # warm_start on
    with caplog.at_level(logging.WARNING, logger="dsage_ray.audit.series"):
        record = continued.audit("builtin:random", label="again", step=4000)
    assert seen["overrides"]["surrogate.init"] == str(copy / "checkpoints" / "002-builtin_wall_follower")
    assert seen["seed"] == 3 and seen["budget"] == 6 and seen["out"] == copy / "checkpoints" / "003-again"
    assert record.error == "simulator actor died with a traceback" and record.new_failures == 0
    assert record.suite_size == len(series.suite) and record.suite_success_rate is not None
    assert [r.getMessage() for r in caplog.records] == [
        "audit-series: checkpoint 3 (again) failed, the series goes on: simulator actor died with a traceback"]
    assert json.loads((copy / SERIES_FILE).read_text())["records"][3]["error"] == record.error
    assert set(record.scalars()) == {"audit/suite_success_rate", "audit/fixed", "audit/regressed", "audit/wall_time"}


def test_a_surrogate_init_override_starts_every_search_from_that_source(series, tmp_path, monkeypatch):
    import dsage_ray.audit.series as module

    copy = tmp_path / "copy"
    shutil.copytree(series.out_dir, copy)
    first = str(series.records[0].audit_dir)
    seen = {}

    def recording_audit(**kwargs):
        seen.update(kwargs)
        raise RuntimeError("stop here")

    monkeypatch.setattr(module, "run_audit", recording_audit)
    settings = {**SETTINGS, "overrides": {**TINY, "surrogate.init": first}}
    AuditSeries(out_dir=copy, **settings).audit("builtin:random", label="again")
    assert seen["overrides"]["surrogate.init"] == first  # not the last audit's folder


def test_scalars_and_tensorboard(series):
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    assert set(series.records[2].scalars()) == {
        "audit/suite_success_rate", "audit/fixed", "audit/regressed", "audit/new_failures", "audit/never_solved",
        "audit/failure_cells", "audit/wall_time"}
    assert series.records[2].scalars()["audit/fixed"] == len(series.records[2].fixed)
    assert set(series.records[1].scalars()) == {"audit/wall_time"}
    events = EventAccumulator(str(series.tensorboard_dir))
    events.Reload()
    assert [e.step for e in events.Scalars("audit/suite_success_rate")] == [3000]
    assert [e.step for e in events.Scalars("audit/new_failures")] == [1000, 3000]
    assert SeriesRecord.from_json(series.records[2].to_json(series.out_dir), series.out_dir) == series.records[2]


def test_the_report_has_the_timeline_the_checkpoints_and_the_matrix(series):
    page = (series.out_dir / SERIES_REPORT).read_text()
    assert page.startswith("<!DOCTYPE html>") and "data:image/png;base64," in page
    assert "Levels × checkpoints" in page and "class='sortable matrix'" in page
    matrix = page[page.index("class='sortable matrix'"):]
    assert matrix.count("<tr") == len(series.suite) + 1  # the header row, then one row per suite level
    for href in set(re.findall(r"href='([^'#]+)'", page)):
        assert (series.out_dir / href).is_file(), href
    reports = [href for href in re.findall(r"href='([^']+)'", page) if href.endswith("report.html")]
    assert len(reports) == 2  # the two checkpoints whose audit ran
    assert "agent &#x27;builtin:nope&#x27;" in page  # the failed checkpoint's error


def cli(argv: list[str]) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(["audit-series", *argv])
    return code, out.getvalue(), err.getvalue()


def test_the_command_end_to_end_and_again(tmp_path):
    out = tmp_path / "cli"
    argv = ["builtin:random", "--out", str(out), "--no-warm-start", *TINY_ARGS]
    code, stdout, _ = cli(argv)
    assert code == 0, stdout
    assert "#0 builtin:random: suite success n/a (0 levels)" in stdout
    assert f"series: {out / SERIES_FILE} (1 checkpoints" in stdout and f"report: {out / SERIES_REPORT}" in stdout
    assert re.search(r"TensorBoard: \S*tensorboard --logdir \S*cli/tensorboard", stdout)
    code, stdout, _ = cli(argv)
    assert code == 0 and "#0 builtin:random: already recorded, skipped" in stdout
    assert len(json.loads((out / SERIES_FILE).read_text())["records"]) == 1


@pytest.mark.parametrize("argv, message", [
    (["builtin:random", "builtin:nope"], "agent 'builtin:nope': builtin agent 'nope': unknown"),
    (["--watch", "{tmp}/missing"], "--watch {tmp}/missing: no such folder"),
    (["--watch", "{tmp}", "--kind", "astar"], "domain 'maze' does not play 'astar' agents"),
    ([], "give checkpoint SPECs to audit in order, or --watch DIR"),
    (["builtin:random", "--budget", "0"], "budget must be positive, got 0"),
])
def test_the_command_refuses_bad_input_before_writing_anything(tmp_path, argv, message):
    out = tmp_path / "never"
    code, stdout, stderr = cli([arg.format(tmp=tmp_path) for arg in argv] + ["--out", str(out), "--local"])
    assert code == 2 and stderr.count("\n") == 1, stderr
    assert stderr.startswith("dsage-ray audit-series: error: ") and message.format(tmp=tmp_path) in stderr
    assert not out.exists() and stdout == ""


def test_watched_checkpoints_come_oldest_first_once_settled(tmp_path):
    from dsage_ray.audit.cli import watched_checkpoints

    now = time.time()
    for name, age in (("ckpt_b", 100), ("ckpt_a", 50), ("ckpt_new", 1), (".ckpt_staging", 100), ("notes.txt", 100)):
        path = tmp_path / name
        if name.startswith("ckpt") or name.startswith("."):
            path.mkdir()
            (path / "weights.pt").write_text("x")
            os.utime(path / "weights.pt", (now - age, now - age))
        else:
            path.write_text("x")
        os.utime(path, (now - age, now - age))
    names = lambda **kw: [p.name for p in watched_checkpoints(tmp_path, now=now, **kw)]  # noqa: E731
    assert names(pattern="ckpt_*", settle=10) == ["ckpt_b", "ckpt_a"]
    assert names(settle=0) == ["ckpt_b", "notes.txt", "ckpt_a", "ckpt_new"]


def test_watching_audits_new_checkpoints_and_a_broken_one_does_not_stop_it(tmp_path):
    """A watched checkpoint that does not load is recorded with its error (exit code 1), not refused."""
    watch = tmp_path / "checkpoints"
    watch.mkdir()
    (watch / "checkpoint_000001").mkdir()
    (watch / "checkpoint_000001" / "garbage").write_text("not a checkpoint")
    old = time.time() - 60
    os.utime(watch / "checkpoint_000001" / "garbage", (old, old))
    out = tmp_path / "watched"
    code, stdout, stderr = cli(["--watch", str(watch), "--pattern", "checkpoint_*", "--poll", "0.05",
                                "--max-checkpoints", "1", "--out", str(out), *TINY_ARGS])
    assert code == 1, stdout + stderr
    assert "#0 checkpoint_000001: FAILED: agent 'rllib:" in stdout and f"series: {out / SERIES_FILE}" in stdout
    assert stderr.startswith("dsage-ray audit-series: 1 of 1 checkpoint audits failed")
    record = json.loads((out / SERIES_FILE).read_text())["records"][0]
    assert record["agent"] == f"rllib:{(watch / 'checkpoint_000001').resolve()}" and record["error"]


def synthetic_series(checkpoints: int = 12, per_checkpoint: int = 4) -> dict:
    """A series.json of ``checkpoints`` records, ``per_checkpoint`` new levels each, one failed audit (#3)."""
    rng = np.random.default_rng(0)
    records, suite = [], []
    for k in range(checkpoints):
        previous = {lv["id"]: lv["results"][str(k - 1)] for lv in suite if str(k - 1) in lv["results"]}
        for lv in suite:
            lv["results"][str(k)] = float(rng.choice([0.0, 0.2, 0.6, 1.0]))
        fixed, regressed = fixed_and_regressed(previous, {lv["id"]: lv["results"][str(k)] for lv in suite})
        error = "agent 'rllib:/a/rather/long/path/checkpoint_000015': not found" if k == 3 else None
        new = 0 if error else per_checkpoint
        suite += [{"id": len(suite) + i, "seed": 1, "origin": k, "level_file": None, "results": {str(k): 0.0},
                   "solution": []} for i in range(new)]
        records.append({"index": k, "label": f"/a/rather/long/path/to/the/run/checkpoint_{k:06d}",
                        "agent": f"rllib:/a/rather/long/path/to/the/run/checkpoint_{k:06d}", "step": 40_000 * k,
                        "suite_size": len(previous), "suite_success_rate": 0.5 if previous else None,
                        "fixed": list(fixed), "regressed": list(regressed), "new_failures": new,
                        "summary": {} if error else {"never_solved": 3, "failure_cells": 9}, "audit_dir": None,
                        "wall_time": 200.0, "error": error})
    return {"domain": "maze", "preset": "cpu", "budget": 500, "episodes": 50, "warm_start": True,
            "failing": "failure rate (1 - success rate) >= 0.5", "records": records, "suite": suite}


def test_the_report_fits_a_phone_and_its_matrix_sorts(browser, tmp_path):
    """At 390 px wide nothing scrolls the page sideways; the wide tables scroll in their box; a checkpoint's
    column sorts the matrix; the page logs no error."""
    from selenium.webdriver.common.by import By

    from dsage_ray.audit.series_report import write_series_report

    data = synthetic_series()
    page = write_series_report(tmp_path, data)
    browser.execute_cdp_cmd("Emulation.setDeviceMetricsOverride",
                            {"width": 390, "height": 844, "deviceScaleFactor": 1, "mobile": True})
    try:
        browser.get(page.resolve().as_uri())
        assert browser.execute_script("return document.documentElement.scrollWidth") <= 390
        for box in ("div.hscroll", "div.scroll"):
            inner, outer = browser.execute_script(
                f"var b = document.querySelector('{box}'); return [b.scrollWidth, b.clientWidth];")
            assert inner > outer and outer <= 390, box
        last = data["records"][-1]["index"]
        header = browser.find_element(By.XPATH,
                                      f"//table[contains(@class, 'matrix')]//th[.//button[text()='#{last}']]")
        header.find_element(By.TAG_NAME, "button").click()
        rates = browser.execute_script(
            "return Array.from(document.querySelectorAll('table.matrix tbody tr'), "
            "r => r.lastElementChild.textContent);")
        assert len(rates) == len(data["suite"])
        assert [float(r) for r in rates] == sorted(float(r) for r in rates)
        assert header.get_attribute("aria-sort") == "ascending"
        assert not [e for e in browser.get_log("browser") if e["level"] == "SEVERE"]
    finally:
        browser.execute_cdp_cmd("Emulation.clearDeviceMetricsOverride", {})
