import json

import pytest

import dsage_ray.agents
import dsage_ray.domains.maze.agents
from dsage_ray.cli import main

from .conftest import DATA, UniformRandomAgent


@pytest.fixture(autouse=True)
def fake_loader(monkeypatch):
    def fake_load_agent(spec):
        if spec != "test:random":
            raise dsage_ray.agents.base.AgentError(f"agent spec {spec!r}: unknown kind")
        return UniformRandomAgent(3)

    monkeypatch.setattr(dsage_ray.domains.maze.agents, "load_maze_agent", fake_load_agent, raising=False)


def test_eval_json_and_render(tmp_path, capsys):
    out = tmp_path / "occ.png"
    code = main(["maze", "eval", "--agent", "test:random", "--layout", str(DATA / "small.txt"),
                 "--episodes", "4", "--seed", "1", "--json", "--render", str(out)])
    assert code == 0
    result = json.loads(capsys.readouterr().out)
    assert {"success_rate", "mean_path_length", "num_walls", "episodes"} <= set(result)
    assert result["episodes"] == 4 and result["num_walls"] == 7
    assert out.read_bytes()[:4] == b"\x89PNG"


def test_eval_table(capsys):
    assert main(["maze", "eval", "--agent", "test:random", "--layout", str(DATA / "corridor_sg.txt"),
                 "--episodes", "2"]) == 0
    assert "success rate" in capsys.readouterr().out


@pytest.mark.parametrize(
    "args, message",
    [
        (["--agent", "test:random", "--layout", "MISSING.txt"], "cannot read layout"),
        (["--agent", "nope:x", "--layout", str(DATA / "small.txt")], "unknown kind"),
        (["--agent", "test:random", "--layout", str(DATA / "small.txt"), "--episodes", "0"], "must be positive"),
    ],
)
def test_bad_input_exits_with_one_line(args, message, capsys):
    assert main(["maze", "eval", *args]) == 2
    text = capsys.readouterr().err
    assert message in text and text.count("\n") == 1 and text.startswith("dsage-ray maze eval: error:")


def test_malformed_layout_names_line(tmp_path, capsys):
    bad = tmp_path / "bad.txt"
    bad.write_text("S..\n.?.\n..G\n")
    assert main(["maze", "eval", "--agent", "test:random", "--layout", str(bad)]) == 2
    assert "bad.txt:2: unknown character" in capsys.readouterr().err
