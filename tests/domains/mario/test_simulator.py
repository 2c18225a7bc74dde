"""The JPype game loop, the deterministic A* timer and agreement with the jar's own player."""

from __future__ import annotations

import dataclasses
import re
import subprocess
import threading

import numpy as np
import pytest

from .conftest import needs_java, needs_javac

pytestmark = [needs_java, pytest.mark.mario]


def _summary(episode) -> tuple:
    return (episode.status, episode.completion, episode.jumps, episode.kills, episode.ticks,
            tuple(sorted(episode.extra.items())), episode.path.tobytes())


def test_flat_level_matches_the_jars_command_line_player(tmp_level_file, flat_level):
    """``java -cp PlayAstar.jar PlayAstar LEVEL norender`` plays large Mario, timer 200, stock
    40 ms A* timer, at 30 fps; our loop under the same settings must report the same result."""
    from dsage_ray.domains.mario.simulator import MarioSimulator, jar_path

    proc = subprocess.run(["java", "-Djava.awt.headless=true", "-cp", str(jar_path()), "PlayAstar",
                           str(tmp_level_file), "norender"], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    out = proc.stdout

    def grab(pattern: str) -> str:
        match = re.search(pattern, out)
        assert match, f"{pattern!r} not in the jar's output:\n{out}"
        return match.group(1)

    episode = MarioSimulator(timer=200, astar_iterations=0, mario_state=1).play(flat_level)
    assert episode.status == grab(r"Game Status: (\w+)") == "WIN"
    assert episode.completion == pytest.approx(float(grab(r"Percentage Completion: ([\d.]+)")))
    assert episode.extra["coins"] == int(grab(r"Coins: (\d+)")) == 4
    assert episode.extra["lives"] == int(grab(r"Lives: (\d+)"))
    assert episode.extra["mario_mode"] == int(grab(r"Mario State: (\d+)")) == 1
    assert episode.kills == int(grab(r"Total Kills: (\d+)"))
    assert episode.jumps == int(grab(r"Jumps: (\d+)"))
    assert -(-episode.extra["remaining_time_ms"] // 1000) == int(grab(r"Remaining Time: (\d+)"))
    assert not episode.deterministic


@needs_javac
def test_deterministic_timer_repeats_exactly(obstacle_level):
    from dsage_ray.domains.mario.simulator import MarioSimulator

    simulator = MarioSimulator(timer=8, astar_iterations=300)
    first, second = simulator.play(obstacle_level), simulator.play(obstacle_level)
    assert first.deterministic and first.ok
    assert first.ticks > 20 and first.jumps >= 1  # the gap and pipe need jumps: the test is not trivial
    assert _summary(first) == _summary(second)
    # The search it cost is counted, and is as repeatable: at least one iteration a tick, at most the budget.
    assert first.ticks <= first.search_iterations == second.search_iterations <= 300 * first.ticks


@needs_javac
def test_deterministic_timer_repeats_across_threads(obstacle_level):
    from dsage_ray.domains.mario.simulator import MarioSimulator

    simulator = MarioSimulator(timer=8, astar_iterations=300)
    reference = _summary(simulator.play(obstacle_level))
    results: list = [None, None]

    def worker(i: int) -> None:
        results[i] = _summary(simulator.play(obstacle_level))

    threads = [threading.Thread(target=worker, args=(i,)) for i in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(timeout=120)
    assert results == [reference, reference]


@needs_javac
def test_iteration_budget_changes_the_agent():
    """The budget must actually reach the A*: with almost no search Mario plays differently."""
    from dsage_ray.domains.mario.simulator import MarioSimulator

    from .conftest import join, level_rows

    rows = level_rows(30)
    for col in range(8, 12):  # a wide gap
        rows[14][col] = rows[15][col] = "-"
    level = join(rows)
    weak = MarioSimulator(timer=5, astar_iterations=1).play(level)
    strong = MarioSimulator(timer=5, astar_iterations=300).play(level)
    assert strong.status == "WIN"
    assert _summary(weak) != _summary(strong)
    assert weak.search_iterations == weak.ticks  # one iteration a tick: the budget, spent every time


def test_small_mario_is_the_default(flat_level):
    from dsage_ray.domains.mario.simulator import MarioSimulator

    episode = MarioSimulator(timer=5, astar_iterations=50).play(flat_level)
    assert episode.extra["mario_mode"] == 0
    assert episode.path.shape == (episode.ticks, 2) and episode.path.dtype == np.float32
    assert 0 < episode.path[0, 0] < episode.path[-1, 0]


def test_wall_clock_timeout_stops_the_episode(obstacle_level):
    from dsage_ray.domains.mario.simulator import WALL_CLOCK_TIMEOUT, MarioSimulator

    episode = MarioSimulator(timer=20, astar_iterations=1000, episode_timeout_s=0.05).play(obstacle_level)
    assert episode.status == WALL_CLOCK_TIMEOUT and not episode.ok
    assert "wall clock" in episode.error


def test_java_exceptions_become_a_failed_episode(monkeypatch, flat_level):
    """A Java exception inside the loop is reported with its Java class and message."""
    import jpype

    from dsage_ray.domains.mario import simulator as sim

    handles = sim.java()
    integer = jpype.JClass("java.lang.Integer")

    def broken_world(*args):
        return integer.parseInt("not a number")  # throws java.lang.NumberFormatException

    monkeypatch.setattr(sim, "_java", dataclasses.replace(handles, MarioWorld=broken_world))
    episode = sim.MarioSimulator(timer=5, astar_iterations=10).play(flat_level)
    assert episode.status == sim.JAVA_ERROR and not episode.ok
    assert "java.lang.NumberFormatException" in episode.error and "not a number" in episode.error


def test_invalid_levels_never_reach_java():
    from dsage_ray.domains.mario.simulator import MarioSimulator
    from dsage_ray.domains.mario.tiles import LevelError

    with pytest.raises(LevelError, match="at least 2 columns"):
        MarioSimulator().play("\n".join(["X"] * 16))


def test_timer_class_compiles_into_the_cache(tmp_path, monkeypatch):
    from dsage_ray.domains.mario import simulator as sim

    if sim.shutil.which("javac") is None:
        assert sim.compile_timer_class() is None
        return
    monkeypatch.setenv(sim.CACHE_ENV, str(tmp_path))
    folder = sim.compile_timer_class()
    assert folder.parent == tmp_path and (folder / "dsagemario" / "DeterministicTimer.class").is_file()
    assert sim.compile_timer_class() == folder  # cached
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".compile-")]  # no temp leftovers


def test_the_jvm_runs_without_jpypes_link_to_pythons_garbage_collector():
    import gc

    import _jpype

    from dsage_ray.domains.mario.simulator import java

    java()
    # Linked, a DSAGE run's Python collections kept JPype's reference thread busy (benchmarks/bench_mario_gc.py).
    assert _jpype._collect not in gc.callbacks
