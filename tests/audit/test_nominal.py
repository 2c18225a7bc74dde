"""The nominal check before an audit's search: its rule, its record, and audits it passes, stops and lets through."""

from __future__ import annotations

import json
import math

import pytest
import torch
from torch import nn

from dsage_ray.audit.collection_file import load_collection
from dsage_ray.audit.nominal import (NOMINAL_FILE, NominalCheck, NominalCheckFailed, far_worse_threshold, judge,
                                     read_record)
from dsage_ray.cli import main
from dsage_ray.errors import InputError
from dsage_ray.types import NominalResult

#: A tiny Maze audit: 8 random levels (the tests read the nominal check, not the levels), 4 episodes each, in this
#: process.
MAZE_TINY = ["--preset", "tiny", "--budget", "8", "--set", "n_rand=8", "--set", "maze.episodes=4", "--local"]
#: A tiny gym audit of CartPole.
GYM_TINY = ["--domain", "gym", "--space", "cartpole", "--preset", "tiny", "--budget", "24", "--local"]


def result(**keys) -> NominalResult:
    values = {"level": "a room", "mean_return": 100.0, "return_std": 0.0, "success_rate": 1.0, "episodes": 10,
              "seed": 1, **keys}
    return NominalResult(**values)


class _Spin(nn.Module):
    """A Maze policy that only ever turns left: it never leaves its start."""

    def forward(self, image: torch.Tensor, direction: torch.Tensor) -> torch.Tensor:
        return torch.tensor([[10.0, 0.0, 0.0]]).repeat(image.shape[0], 1)


@pytest.fixture
def spinning_agent(tmp_path) -> str:
    path = tmp_path / "spin.pt"
    torch.jit.script(_Spin()).save(str(path))
    return f"torchscript:{path}"


# ------------------------------------------------------------------------------------------------ the rule


def test_far_worse_is_a_quarter_below_the_expected_return_or_three_standard_errors_where_episodes_spread():
    assert far_worse_threshold(500.0, return_std=0.0, episodes=10) == 375.0
    assert far_worse_threshold(-80.0, return_std=0.0, episodes=10) == -100.0  # |E| for a negative return
    # The RL Zoo's DQN LunarLander: its 10 episodes spread with a standard deviation of 70 around 113.6.
    noisy = far_worse_threshold(113.6, return_std=70.0, episodes=10)
    assert noisy == pytest.approx(113.6 - 3 * 70.0 * math.sqrt(2 / 10))
    assert noisy < 113.6 - 0.25 * 113.6


def test_the_given_figure_goes_before_the_agents_own_and_without_either_only_success_counts():
    own = result(mean_return=100.0, expected_return=300.0, expected_return_source="evaluations.npz")
    check = judge(own)
    assert (check.verdict, check.expected, check.expected_source, check.threshold) == ("far_worse", 300.0,
                                                                                        "evaluations.npz", 225.0)
    told = judge(own, expect_return=120.0)
    assert (told.verdict, told.expected_source) == ("ok", "--expect-return")
    assert judge(result(success_rate=0.0)).verdict == "never_succeeds"
    assert judge(result(success_rate=0.1, mean_return=-1e6)).passed  # no figure: any success passes
    # With a figure, success does not count: the zoo's DQN lander is expected below LunarLander's success line.
    assert judge(result(success_rate=0.0, mean_return=110.0), expect_return=113.6).passed


def test_the_stop_is_one_line_naming_the_numbers_the_cause_and_the_way_on():
    check = judge(result(mean_return=-120.0, return_std=5.0, success_rate=0.0, causes="normalisation missing"),
                  expect_return=272.0)
    message = check.stop_message()
    assert "\n" not in message and "FAR WORSE than expected (-120 < 204)" in message
    assert "expected 272 (--expect-return)" in message and "likely normalisation missing" in message
    assert "--allow-failing-nominal" in message and "nothing was searched" in message


def test_a_record_reads_back_and_a_forged_one_is_refused(tmp_path):
    check = judge(result(mean_return=90.0, expected_return=100.0, expected_return_source="evaluations.npz"))
    again = NominalCheck.from_dict(json.loads(json.dumps(check.to_dict())), where="x")
    assert again == check
    record = check.to_dict()
    for forged in ({**record, "verdict": "fine"}, {**record, "expected": "100"},
                   {**record, "result": {**record["result"], "mean_return": float("nan")}},
                   {**record, "result": {**record["result"], "code": "import os"}}, {"result": 1}):
        with pytest.raises(InputError, match="not a nominal check record"):
            NominalCheck.from_dict(forged, where="x")
    (tmp_path / NOMINAL_FILE).write_text("{not json")
    with pytest.raises(InputError, match="not a nominal check record"):
        read_record(tmp_path)


# ---------------------------------------------------------------------------------------------- audits


def test_a_gym_agent_far_below_the_expected_return_stops_before_anything_is_written(tmp_path, capsys):
    out = tmp_path / "audit"
    assert main(["audit", *GYM_TINY, "--agent", "random", "--expect-return", "400", "--out", str(out)]) == 2
    error = capsys.readouterr().err.strip()
    assert len(error.splitlines()) == 1
    assert "nominal check failed on CartPole-v1 as registered" in error and "FAR WORSE than expected" in error
    assert "observation preprocessing not applied" in error and "environment version" in error
    assert not out.exists()
    with pytest.raises(NominalCheckFailed):  # the same from Python
        from dsage_ray.audit.run import run_audit

        run_audit(domain="gym", agent="random", preset="tiny", local=True, out=out, expect_return=400.0)
    assert not out.exists()


def test_a_maze_agent_that_never_reaches_the_goal_stops_and_allow_failing_nominal_goes_on(spinning_agent, tmp_path,
                                                                                           capsys):
    out = tmp_path / "audit"
    assert main(["audit", *MAZE_TINY, "--agent", spinning_agent, "--out", str(out)]) == 2
    error = capsys.readouterr().err
    assert "an open 16x16 room" in error and "it NEVER SUCCEEDS there" in error and not out.exists()

    assert main(["audit", *MAZE_TINY, "--agent", spinning_agent, "--allow-failing-nominal", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "nominal check: an open 16x16 room" in printed and "(went on: --allow-failing-nominal)" in printed
    recorded = load_collection(out / "collection")["nominal"]
    assert (recorded["verdict"], recorded["allowed"], recorded["result"]["success_rate"]) == ("never_succeeds", True,
                                                                                            0.0)
    page = (out / "collection" / "report.html").read_text()
    assert "<dt>nominal check</dt><dd><span class='bad'>an open 16x16 room" in page
    assert "The agent failed its nominal check" in page


def test_a_good_agent_passes_its_check_is_in_the_header_and_a_collect_only_reuses_it(tmp_path, capsys, monkeypatch):
    out = tmp_path / "audit"
    args = ["audit", *MAZE_TINY, "--agent", "builtin:wall_follower", "--expect-return", "0.9", "--out", str(out)]
    assert main(args) == 0
    printed = capsys.readouterr().out
    line = next(line for line in printed.splitlines() if line.startswith("nominal check:"))
    assert "MiniGrid reward 0.94" in line and "success 1.00" in line and "expected 0.9 (--expect-return)" in line
    assert line.endswith(": ok") and printed.index("nominal check:") < printed.index("collection:")
    record = read_record(out)
    assert record.passed and record.result.episodes == 50
    page = (out / "collection" / "report.html").read_text()
    assert "<dt>nominal check</dt><dd>an open 16x16 room" in page and "expected 0.9 (--expect-return)" in page
    assert "failed its nominal check" not in page

    import dsage_ray.audit.nominal as nominal

    def not_again(*args, **kwargs):
        raise AssertionError("the nominal level was played again")

    monkeypatch.setattr(nominal, "judge", not_again)
    assert main([*args, "--collect-only"]) == 0
    assert "not played again" in capsys.readouterr().out
    assert load_collection(out / "collection")["nominal"] == json.loads((out / NOMINAL_FILE).read_text())


def test_an_agents_own_expected_return_is_the_figure(monkeypatch):
    from dsage_ray.domains.maze.agents.builtin import WallFollowerAgent
    from dsage_ray.audit.nominal import play_nominal
    from dsage_ray.config import RunConfig
    from dsage_ray.domains import build_domain

    monkeypatch.setattr(WallFollowerAgent, "expected_return", 5.0, raising=False)
    monkeypatch.setattr(WallFollowerAgent, "expected_return_source", "its record", raising=False)
    domain = build_domain(RunConfig.build({"domain": "maze", "maze.agent": "builtin:wall_follower"}))
    check = play_nominal(domain, run_seed=0)
    assert (check.verdict, check.expected, check.expected_source) == ("far_worse", 5.0, "its record")
    assert play_nominal(domain, run_seed=0, expect_return=0.9).passed


def test_expect_return_must_be_a_finite_number(tmp_path):
    from dsage_ray.audit.run import run_audit

    with pytest.raises(InputError, match="expect_return must be a finite number"):
        run_audit(agent="builtin:random", preset="tiny", local=True, out=tmp_path / "a", expect_return=float("inf"))
    assert not (tmp_path / "a").exists()
