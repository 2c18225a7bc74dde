"""benchmarks/peer_comparison.py: the ledger's counts (faults, fault cells, budgets) on a fake evaluator."""

from __future__ import annotations

import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
import peer_comparison as pc  # noqa: E402
from dsage_ray.domains.gym.space_model import Parameter  # noqa: E402


class FakeDomain:
    """Faults where x > 0.5; the measures are the level itself, on a 4 × 4 grid over [-1, 1]²."""

    solution_dim = 2
    measure_ranges = ((-1.0, 1.0), (-1.0, 1.0))
    archive_dims = (4, 4)
    space = SimpleNamespace(params=[Parameter(name="force_x", low=-1000, high=1000),
                                    Parameter(name="force_y", low=-1000, high=1000)])

    def __init__(self) -> None:
        self.played = 0

    def evaluate(self, solution, seed, *, episodes=None):
        self.played += 1
        x = float(solution[0])
        return SimpleNamespace(objective=1.0 if x > 0.5 else 0.0, measures=np.asarray(solution, dtype=float),
                               info={"mean_return": -x})


class FakeClock:
    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        self.now += 1.0  # each reading: one more second
        return self.now


def test_cell_of_clips_to_the_edge_cells():
    assert pc.cell_of(np.array([-1.0, 0.99]), ranges=((-1, 1), (-1, 1)), dims=(4, 4)) == (0, 3)
    assert pc.cell_of(np.array([-5.0, 5.0]), ranges=((-1, 1), (-1, 1)), dims=(4, 4)) == (0, 3)
    assert pc.cell_of(np.array([0.1, -0.1]), ranges=((-1, 1), (-1, 1)), dims=(4, 4)) == (2, 1)


def test_faults_are_distinct_levels_and_cells_distinct_cells():
    ledger = pc.Ledger(domain=FakeDomain(), episodes=10)
    for level in ([0.6, 0.6], [0.6, 0.6], [0.7, 0.6], [0.9, -0.9], [0.0, 0.0]):
        ledger.play(np.array(level))
    counts = pc.count(ledger.trace, episodes=5)
    # [0.6, 0.6] twice is one fault; [0.6, 0.6] and [0.7, 0.6] share cell (3, 3); [0.9, -0.9] is cell (3, 0).
    assert (counts.faults, counts.fault_cells, counts.cells, counts.episodes) == (3, 2, 3, 5)
    assert counts.lowest_return == pytest.approx(-0.9)
    assert pc.count(ledger.trace, episodes=1).faults == 1


def test_near_copies_of_a_fault_are_one_separate_fault():
    ledger = pc.Ledger(domain=FakeDomain(), episodes=10)
    # 0.6 and 0.605 lie in one 1% bin of the box (0.02 wide), 0.63 in the next; all three fail (x > 0.5).
    for level in ([0.6, 0.6], [0.605, 0.6], [0.63, 0.6], [0.0, 0.0]):
        ledger.play(np.array(level))
    counts = pc.count(ledger.trace, episodes=4)
    assert (counts.faults, counts.separate_faults) == (3, 2)


def test_the_points_of_one_integer_level_are_one_level_and_one_fault():
    domain = FakeDomain()
    domain.space = SimpleNamespace(params=[Parameter(name="row", kind="int", low=0, high=4),
                                           Parameter(name="force_y", low=-1000, high=1000)])
    ledger = pc.Ledger(domain=domain, episodes=10)
    for level in ([1.0, 0.3], [0.9, 0.3], [0.6, 0.3]):  # rows 4, 4 (3.8 rounds up) and 3
        ledger.play(np.array(level))
    assert [row["level"][0] for row in ledger.trace] == [1.0, 1.0, 0.5]
    assert pc.count(ledger.trace, episodes=3).faults == 1  # row 4 twice (x > 0.5 fails here): one fault


def test_the_one_coordinate_mutation_redraws_one_integer_nearer_values_likelier():
    rng = np.random.default_rng(0)
    low, high = np.array([0.0, 0.0]), np.array([10.0, 1.0])
    mutants = np.array([pc.redraw_one_coordinate(np.array([5.0, 0.0]), rng, low=low, high=high)
                        for _ in range(2000)])
    changed = (mutants != [5.0, 0.0]).sum(axis=1)
    assert (changed == 1).all()  # always one coordinate, always to another value
    first = mutants[mutants[:, 1] == 0.0, 0]
    assert set(first) <= set(range(11)) - {5} and 0.0 not in first and 10.0 not in first  # the farthest: weight 0
    assert (np.abs(first - 5) == 1).mean() > (np.abs(first - 5) == 4).mean()
    assert set(mutants[mutants[:, 0] == 5.0, 1]) == {1.0}  # two values: the other one


def test_the_cpu_reading_counts_the_episodes_that_ended_within_it():
    ledger = pc.Ledger(domain=FakeDomain(), episodes=10, clock=FakeClock())
    for x in (0.6, 0.7, 0.8, 0.9):
        ledger.play(np.array([x, 0.0]))
    cpu = [row["cpu"] for row in ledger.trace]
    assert cpu == sorted(cpu) and len(set(cpu)) == 4
    assert pc.count(ledger.trace, cpu=cpu[1]).episodes == 2
    assert pc.count(ledger.trace, cpu=cpu[1]).faults == 2
    with pytest.raises(ValueError):
        pc.count(ledger.trace)


def test_the_ledger_stops_at_the_episodes_then_at_the_cpu_budget():
    domain = FakeDomain()
    ledger = pc.Ledger(domain=domain, episodes=3)
    for _ in range(3):
        ledger.play(np.zeros(2))
    with pytest.raises(pc.BudgetSpent):
        ledger.play(np.zeros(2))
    assert domain.played == 3
    # With a CPU budget it goes on past the episodes until the clock has passed it (one second per reading here).
    ledger = pc.Ledger(domain=FakeDomain(), episodes=1, cpu=6.0, clock=FakeClock())
    played = 0
    with pytest.raises(pc.BudgetSpent):
        while True:
            ledger.play(np.zeros(2))
            played += 1
    assert played > 1 and ledger.trace[-1]["cpu"] >= 6.0 - 2


def test_levels_outside_the_box_are_clipped_before_they_are_played():
    ledger = pc.Ledger(domain=FakeDomain(), episodes=2)
    ledger.play(np.array([3.0, -3.0]))
    assert ledger.trace[0]["level"] == [1.0, -1.0] and ledger.trace[0]["fault"]


def test_the_table_reads_each_run_at_equal_episodes_and_at_the_dsage_cpu_of_its_seed():
    def record(arm, seed, faults_at):
        trace = [{"level": [0.1 * i, 0.0], "fault": i in faults_at, "return": 0.0, "cell": [i, 0], "cpu": float(i)}
                 for i in range(6)]
        return {"arm": arm, "seed": seed, "tag": "t", "episodes": 4, "trace": trace}

    # dsage spends 3 CPU s (its last episode); rt finds a fault at episode 5 (after the 4-episode budget and after
    # 3 s), so it counts at neither; tpe's fault at episode 2 counts at both.
    records = [record("dsage", 1, {0}), record("rt", 1, {5}), record("tpe", 1, {2}), record("mdpfuzz", 1, {1})]
    records[0]["trace"] = records[0]["trace"][:4]
    records[3]["trace"] = records[3]["trace"][:2]  # stopped at 2 episodes: short of the budget and of dsage's CPU
    lines = {line.split(" | ")[0].lstrip("| "): line for line in pc.table(records).splitlines()}
    # faults, faults at 1% and fault cells: at equal episodes, then at equal CPU
    assert lines["rt"].split(" | ")[2:5] == ["0.0", "0.0", "0.0"]
    assert lines["rt"].split(" | ")[8:11] == ["0.0", "0.0", "0.0"]
    assert lines["tpe"].split(" | ")[2:5] == ["1.0", "1.0", "1.0"]
    assert lines["tpe"].split(" | ")[8:11] == ["1.0", "1.0", "1.0"]
    assert lines["tpe"].rstrip(" |").split(" | ")[-1] == "4"  # episodes that ended within dsage's 3 s: 0..3
    assert "short: 2-2 episodes" in lines["mdpfuzz"].split(" | ")[2]
    assert lines["mdpfuzz"].rstrip(" |").split(" | ")[-1] == "2 (1 short)"


def test_tpe_plays_through_the_ledger_until_it_is_spent():
    pytest.importorskip("optuna")
    pytest.importorskip("ray.tune.search.optuna")
    ledger = pc.Ledger(domain=FakeDomain(), episodes=12)
    pc.run_tpe(ledger, seed=0, config=pc.Config(tpe_startup=4))
    assert len(ledger.trace) == 12


def test_indago_plays_the_classifiers_picks_once_both_classes_are_seen():
    pytest.importorskip("sklearn")
    ledger = pc.Ledger(domain=FakeDomain(), episodes=40)
    config = pc.Config(indago_warmup=20, indago_picks=5, indago_population=30, indago_generations=3)
    pc.run_indago(ledger, seed=0, config=config)
    assert len(ledger.trace) == 40
    after = ledger.trace[20:]
    # The classifier learns x > 0.5 fails: its picks fail far more often than the warm-up's random levels (~25%).
    assert sum(row["fault"] for row in after) / len(after) > 0.6
