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
    ({"measures": {"x": {"info": "k", "at": "middle", "range": [0, 1]}}}, "at must be one of 'end', 'mean', 'min', 'max', 'first'"),
    ({"measures": {"x": {"obs": 0, "at": "first", "range": [0, 1]}}}, "at = \"first\" needs when"),
    ({"measures": {"x": {"obs": 0, "when": "obs[0] > 0", "otherwise": "end", "range": [0, 1]}}},
     "when and otherwise go with at = \"first\""),
    ({"measures": {"x": {"obs": 0, "at": "first", "when": "speed > 0", "otherwise": "end", "range": [0, 1]}}},
     "names 'speed' (known: obs, reward, info, step)"),
    ({"measures": {"x": {"obs": 0, "at": "first", "when": "obs[1] > 0", "otherwise": "later", "range": [0, 1]}}},
     "otherwise must be"),
    ({"measures": {"x": {"param": "length", "at": "mean"}}}, "a parameter is known before the episode"),
    ({"fault": {}}, "declare at least one test"),
    ({"fault": {"last_reward_below": -100}}, "unknown key(s) last_reward_below"),
    ({"fault": {"last_reward_at_most": "low"}}, "last_reward_at_most must be a number"),
    ({"fault": {"terminated": 1}}, "terminated must be true or false"),
    ({"fault": {"condition": "import os"}}, "is not an expression"),
    ({"env": {"id": "CartPole-v1", "setup": "hook.py:f"}}, "expected \"python:FILE.py:FUNCTION\""),
    ({"env": {"id": "CartPole-v1", "setup": "python:hook.py"}}, "expected \"python:FILE.py:FUNCTION\""),
    ({"env": {"id": "CartPole-v1", "deterministic": "yes"}}, "deterministic: must be true or false"),
    ({"env": {"id": "CartPole-v1", "reset_seed": -1}}, "reset_seed: must be a non-negative integer"),
    ({"params": {"force": {"range": [0, 1], "setup": True}}}, "go to the setup hook (setup = true), but [env] names"),
    ({"params": {"force": {"range": [0, 1], "setup": "force"}}}, "setup = true sends the parameter"),
    # Bounds a file from someone else cannot pass: memory allocated away, an episode played for ever.
    ({"measures": {"x": {"obs": 0, "range": [0, 1], "cells": 10**6}}}, "cells must be an integer in [1, 1,000]"),
    ({"occupancy": {"x": {"obs": 0, "range": [0, 1]}, "y": {"obs": 1, "range": [0, 1]}, "bins": [10**5, 8]}},
     "bins: expected two integers in [1, 256]"),
    ({"env": {"id": "CartPole-v1", "max_episode_steps": 10**15}}, "max_episode_steps: must be an integer in [1, 1,000,000]"),
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


def test_a_fault_replaces_the_success_test_and_round_trips():
    tables = {key: value for key, value in SPACE.items() if key != "success"}
    space = build_space({**tables, "fault": {"last_reward_at_most": -100, "terminated": True}})
    assert space.fault.describe() == "fault: last reward <= -100 and terminated"
    assert build_space(space.to_dict()).fault == space.fault
    crash = dict(last_reward=-100.0, episode_return=-250.0, length=80, terminated=True, truncated=False, info={},
                 observation=np.zeros(8))
    assert space.fault.happened(**crash)
    assert not space.fault.happened(**{**crash, "last_reward": -99.0})
    assert not space.fault.happened(**{**crash, "terminated": False, "truncated": True})


def test_a_fault_condition_and_info_key_are_read_off_the_last_step():
    space = build_space({**SPACE, "fault": {"info": "collided", "condition": "obs[0] > 1"}})
    last = dict(last_reward=0.0, episode_return=0.0, length=5, terminated=True, truncated=False,
                observation=np.array([2.0, 0.0]))
    assert space.fault.happened(info={"collided": True}, **last)
    assert not space.fault.happened(info={"collided": False}, **last)
    assert not space.fault.happened(info={"collided": True}, **{**last, "observation": np.array([0.5, 0.0])})


def test_setup_hooks_deterministic_spaces_and_event_measures_round_trip():
    space = build_space({**SPACE,
                         "env": {"id": "LunarLander-v3", "setup": "python:hook.py:push", "deterministic": True,
                                 "reset_seed": 0},
                         "params": {"force_x": {"range": [-1000, 1000], "setup": True}},
                         "measures": {"contact_x": {"obs": 0, "at": "first", "when": "obs[6] > 0 or obs[7] > 0",
                                                    "otherwise": "min", "range": [-1, 1]},
                                      "late": {"obs": 1, "at": "first", "when": "step >= 3", "otherwise": -2,
                                               "range": [-1, 1]}},
                         "audit": {"measures": ["contact_x", "late"]}})
    assert (space.setup, space.deterministic, space.reset_seed) == ("python:hook.py:push", True, 0)
    assert space.params[0].target == "setup" and "setup hook" in space.params[0].describe()
    signal = space.measure("contact_x").signal
    assert (signal.at, signal.when, signal.otherwise) == ("first", "obs[6] > 0 or obs[7] > 0", "min")
    assert space.measure("late").signal.otherwise == -2.0
    again = build_space(space.to_dict())
    assert again.measures == space.measures and again.params == space.params
    assert (again.setup, again.deterministic, again.reset_seed) == (space.setup, True, 0)


def test_a_nominal_table_names_parameters_with_values_in_their_ranges():
    space = build_space({**SPACE, "nominal": {"length": 0.5, "mode": "a"}})
    assert space.nominal == {"length": 0.5, "mode": "a"}
    assert build_space(space.to_dict()).nominal == space.nominal  # level files keep it
    nominal, values = space.nominal_level()
    assert [p.name for p in nominal.params] == ["length", "mode"] and values == {"length": 0.5, "mode": "a"}
    bare, none = build_space(SPACE).nominal_level()
    assert bare.params == () and none == {} and bare.env_id == "CartPole-v1"  # the environment as registered
    for table, message in (({"lenght": 0.5}, r"\[nominal\] lenght: not a parameter of the space .*did you mean"),
                           ({"length": 3.0}, r"\[nominal\] length: .*3 is outside its range \[0.25, 2\]"),
                           ({"mode": "d"}, r"\[nominal\] mode: .*'d' is not one of \['a', 'b', 'c'\]"),
                           ({"n": "2"}, r"\[nominal\] n: .*'2' is not a number")):
        with pytest.raises(SpaceError, match=message):
            build_space({**SPACE, "nominal": table}, source="s.toml")
    with pytest.raises(SpaceError, match="nominal must be a table"):
        build_space({**SPACE, "nominal": 1})


def test_the_shipped_lunarlander_is_nominally_windless():
    tables, source = read_space_tables("lunarlander")
    space = build_space(tables, source=source)
    assert space.env_args == {"enable_wind": True} and space.nominal == {"wind_power": 0.0, "turbulence_power": 0.0}
