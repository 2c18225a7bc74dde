"""Regression audits: the objective's math, the domain's paired evaluation, and a tiny audit end to end."""

from __future__ import annotations

import json
import shlex

import numpy as np
import pytest

from dsage_ray.audit.collection import audit_config
from dsage_ray.audit.collection_file import load_collection
from dsage_ray.cli import main
from dsage_ray.config import ConfigError, RunConfig
from dsage_ray.domains.maze.domain import MazeDomain
from dsage_ray.domains.maze.evaluate import evaluate
from dsage_ray.domains.maze.layout import parse_layout
from dsage_ray.domains.maze.level import MazeLevel
from dsage_ray.domains.maze.measures import OBJECTIVES, regression_score
from dsage_ray.domains.maze.plugin import MazeConfig

NEW, OLD = "builtin:wall_follower", "builtin:random"


def test_regression_score_maps_the_success_difference_onto_0_1():
    assert regression_score(success_rate=0.3, reference_success_rate=0.3) == 0.5  # no difference
    assert regression_score(success_rate=0.0, reference_success_rate=1.0) == 1.0  # the worst regression
    assert regression_score(success_rate=1.0, reference_success_rate=0.0) == 0.0  # the best improvement
    assert regression_score(success_rate=0.2, reference_success_rate=0.7) == pytest.approx(0.75)
    # Monotone in the difference and nowhere negative.
    deltas = np.linspace(-1, 1, 21)
    scores = [regression_score(success_rate=0.5 - d / 2, reference_success_rate=0.5 + d / 2) for d in deltas]
    assert np.all(np.diff(scores) > 0) and min(scores) >= 0 and max(scores) <= 1


def test_regression_objective_needs_the_reference_and_scores_invalid_levels_0():
    level = parse_layout("S.#.\n....\n.#.G\n")
    from dsage_ray.domains.maze.agents import load_maze_agent

    new = evaluate(level, load_maze_agent(NEW), episodes=6, seed=1)
    old = evaluate(level, load_maze_agent(OLD), episodes=6, seed=1)
    assert OBJECTIVES["regression"](new, old) == pytest.approx((1 + old.success_rate - new.success_rate) / 2)
    with pytest.raises(ValueError, match="reference"):
        OBJECTIVES["regression"](new)
    invalid = evaluate(MazeLevel.from_bitmap(np.ones((4, 4))), None, episodes=3)
    assert OBJECTIVES["regression"](invalid, None) == 0.0


def test_domain_runs_both_agents_on_the_same_seed():
    domain = MazeDomain(config=MazeConfig(height=4, width=4, episodes=8, agent=NEW, reference=OLD,
                                          objective="regression", measures=("num_walls", "mean_path_length"),
                                          archive_dims=(16, 10)))
    rng = np.random.default_rng(0)
    solution = next(s for s in domain.random_solutions(50, rng) if domain.is_valid(s))
    result = domain.evaluate(solution, seed=11)
    from dsage_ray.domains.maze.agents import load_maze_agent

    level = domain.level(solution)
    new = evaluate(level, load_maze_agent(NEW), episodes=8, seed=11)
    old = evaluate(level, load_maze_agent(OLD), episodes=8, seed=11)
    assert result.info["success_rate"] == new.success_rate
    assert result.info["reference"] == {"success_rate": old.success_rate, "mean_path_length": old.mean_path_length}
    assert result.objective == pytest.approx((1 + old.success_rate - new.success_rate) / 2)
    assert result.measures[1] == new.mean_path_length  # measures describe the audited agent
    assert np.array_equal(result.occupancy, new.occupancy)


def test_config_ties_the_reference_to_the_regression_objective():
    with pytest.raises(ConfigError, match="maze.reference"):
        RunConfig.build({"maze.objective": "regression"})
    with pytest.raises(ConfigError, match="maze.reference"):
        RunConfig.build({"maze.objective": "failure_rate", "maze.reference": OLD})
    assert RunConfig.build({"maze.objective": "regression", "maze.reference": OLD}).maze.reference == OLD
    config = audit_config(agent=NEW, reference=OLD)
    assert (config.maze.objective, config.maze.reference, config.maze.agent) == ("regression", OLD, NEW)
    with pytest.raises(ValueError, match="needs a reference agent"):
        audit_config(agent=NEW, objective="regression")
    with pytest.raises(ValueError, match="needs the 'regression' objective"):
        audit_config(agent=NEW, reference=OLD, objective="failure_rate")


@pytest.fixture(scope="module")
def regression_audit(tmp_path_factory):
    """``dsage-ray audit --agent NEW --reference OLD --local`` on 24 random levels, 6 episodes each."""
    out = tmp_path_factory.mktemp("regression")
    argv = ["audit", "--agent", NEW, "--reference", OLD, "--preset", "tiny", "--budget", "24", "--set", "n_rand=24",
            "--set", "maze.episodes=6", "--seed", "5", "--local", "--out", str(out)]
    return out / "collection", argv


def test_tiny_regression_audit(regression_audit, capsys):
    collection, argv = regression_audit
    assert main(argv) == 0
    printed = capsys.readouterr().out
    c = load_collection(collection)
    assert (c["agent"], c["reference"], c["objective"]) == (NEW, OLD, "regression")
    levels = c["levels"]
    assert levels
    for lv in levels:
        assert set(lv["reference"]) == {"success_rate", "mean_path_length", "seed"}
        assert lv["reference"]["seed"] == lv["seed"]
        assert lv["regression"] == pytest.approx(lv["reference"]["success_rate"] - lv["success_rate"])
        assert lv["objective"] == pytest.approx((1 + lv["regression"]) / 2)
    regressions = [lv["regression"] for lv in levels]
    assert regressions == sorted(regressions, reverse=True), "worst regression first"
    regressed = sum(r > 0 for r in regressions)
    assert f"{regressed} regressed" in printed and "reference" in printed
    assert f"report: {collection / 'report.html'}" in printed

    # Both agents' numbers come back from the CLI with the recorded seed: the entry's own command for the
    # audited agent, the same command with the reference's spec for the reference.
    worst = levels[0]
    for agent, expected in ((NEW, worst), (OLD, worst["reference"])):
        command = shlex.split(worst["reproduce"])
        command[command.index("--agent") + 1] = agent
        assert main(command[1:] + ["--json"]) == 0
        again = json.loads(capsys.readouterr().out)
        assert again["success_rate"] == expected["success_rate"]
        assert again["mean_path_length"] == expected["mean_path_length"]

    # The same --out again is refused before anything is searched or written.
    before = (collection / "collection.json").read_bytes()
    capsys.readouterr()
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "already holds an audit: pass --resume" in err and err.count("\n") == 1
    assert (collection / "collection.json").read_bytes() == before
