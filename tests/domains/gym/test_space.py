"""Parameter spaces: files, --param strings, the box's mapping, and every malformed input named in one line."""

import numpy as np
import pytest

from dsage_ray.domains.gym.space import (SpaceError, build_space, evaluate_expression, parse_param,
                                         read_space_tables, shipped_spaces)

SPACE = {
    "env": {"id": "CartPole-v1", "derived": {"total_mass": "masspole + masscart"}},
    "params": {"length": {"range": [0.25, 2.0], "attr": "length"},
               "n": {"range": [1, 5], "int": True},
               "mode": {"choices": ["a", "b", "c"], "reset": "mode"}},
    "measures": {"x_end": {"obs": 0, "at": "end", "range": [-2.4, 2.4]}, "length": {"range": [0, 500]}},
    "success": {"return_at_least": 475},
    "audit": {"measures": ["x_end", "length"]},
}


def test_values_and_solution_are_inverse_over_the_box():
    space = build_space(SPACE)
    assert [p.name for p in space.params] == ["length", "n", "mode"]
    values = space.values(np.array([-1.0, 1.0, 0.0]))
    assert values == {"length": 0.25, "n": 5, "mode": "b"}
    assert space.values(np.array([3.0, -7.0, 1.0])) == {"length": 2.0, "n": 1, "mode": "c"}  # clipped
    centre = space.values(np.zeros(3))
    assert centre["length"] == pytest.approx(1.125)
    np.testing.assert_allclose(space.solution(values), [-1.0, 1.0, 0.0], atol=1e-6)


def test_parameters_are_measures_and_the_statistics_have_ranges():
    space = build_space(SPACE)
    assert space.measure("param.length").low == 0.25 and space.measure("param.length").high == 2.0
    assert (space.measure("terminated").low, space.measure("terminated").high) == (0.0, 1.0)
    assert space.measure("x_end").signal.source == "obs"


def test_command_line_params_and_env_args_go_over_the_file():
    space = build_space(SPACE, params=["attr.length=0.5:1.0", "gravity=-12:-2"], env_args=["enable_wind=true"])
    by_name = {p.name: p for p in space.params}
    assert (by_name["length"].low, by_name["length"].high, by_name["length"].target) == (0.5, 1.0, "attr")
    assert by_name["gravity"].target == "make" and by_name["gravity"].low == -12.0
    assert space.env_args == {"enable_wind": True}


def test_parse_param_forms():
    assert parse_param("n=1:5:int") == ("n", {"range": [1.0, 5.0], "int": True})
    assert parse_param("mode=a|b|3") == ("mode", {"choices": ["a", "b", 3]})
    assert parse_param("attr.state[2]=-0.2:0.2") == ("state[2]", {"range": [-0.2, 0.2], "attr": "state[2]"})
    assert parse_param("reset.x=0:1") == ("x", {"range": [0.0, 1.0], "reset": "x"})


def test_a_space_round_trips_through_its_tables():
    space = build_space(SPACE)
    again = build_space(space.to_dict())
    assert again.params == space.params and again.success == space.success
    assert again.derived == space.derived and again.audit_measures == space.audit_measures


def test_shipped_spaces_load():
    assert {"cartpole", "lunarlander"} <= set(shipped_spaces())
    for name in shipped_spaces():
        tables, source = read_space_tables(name)
        space = build_space(tables, source=source)
        assert space.audit_measures and len(space.occupancy) == 2


@pytest.mark.parametrize("change, message", [
    ({"params": {"length": {"range": [2.0, 0.25]}}}, "range [2, 0.25] needs low < high"),
    ({"params": {"length": {"range": [1, 1]}}}, "needs low < high"),
    ({"params": {"length": {"rnge": [0, 1]}}}, "unknown key(s) rnge"),
    ({"params": {"length": {"range": [0, 1], "attr": "a", "reset": "b"}}}, "give one of make, reset, attr"),
    ({"params": {"m": {"choices": ["a"]}}}, "a choice needs at least two values"),
    ({"params": {"n": {"range": [0.5, 3], "int": True}}}, "an integer range needs integer bounds"),
    ({"measures": {"x": {"range": [0, 1]}}}, "say what it reads"),
    ({"measures": {"x": {"obs": 0}}}, "needs range = [LOW, HIGH]"),
    ({"measures": {"x": {"info": "k", "at": "middle", "range": [0, 1]}}}, "at must be 'end' or 'mean'"),
    ({"success": {}}, "say how an episode succeeds"),
    ({"audit": {"measures": ["nope"]}}, "unknown measure 'nope'"),
    ({"env": {"id": "CartPole-v1", "derived": {"x": "__import__('os')"}}}, "may hold only numbers"),
    ({"occupancy": {"x": {"obs": 0, "range": [0, 1]}}}, "declare exactly x and y"),
    ({"extra": {}}, "unknown table(s) extra"),
])
def test_malformed_spaces_are_named(change, message):
    tables = {**SPACE, **change}
    with pytest.raises(SpaceError, match=None) as error:
        build_space(tables, source="space.toml")
    assert message in str(error.value) and "\n" not in str(error.value)


@pytest.mark.parametrize("param, message", [
    ("length", "expected NAME=LOW:HIGH"),
    ("length=2:1", "needs low < high"),
    ("length=a:b", "expected LOW:HIGH, LOW:HIGH:int or A|B|C"),
])
def test_malformed_params_are_named(param, message):
    with pytest.raises(SpaceError) as error:
        build_space(SPACE, params=[param])
    assert message in str(error.value)


def test_missing_file_and_unknown_shipped_name(tmp_path):
    with pytest.raises(SpaceError, match="not a shipped space"):
        read_space_tables("cartpol")
    bad = tmp_path / "bad.toml"
    bad.write_text("[env\nid=")
    with pytest.raises(SpaceError, match="not TOML"):
        read_space_tables(str(bad))


def test_derived_expressions_are_arithmetic_only():
    assert evaluate_expression("a * b + 2 ** 2 - -1", {"a": 2.0, "b": 3.0}) == 11.0
    with pytest.raises(KeyError):
        evaluate_expression("a + c", {"a": 1.0})
