"""Space-file expressions: bounded arithmetic and conditions, and every way to hang an audit refused in one line."""

import subprocess
import sys

import numpy as np
import pytest

from dsage_ray.domains.gym.expressions import (MAX_DEPTH, MAX_LENGTH, ExpressionError, evaluate_expression,
                                               parse_arithmetic, parse_condition)
from dsage_ray.domains.gym.space import SpaceError, build_space, merge_space_lines, read_space_tables

HANGING = [
    "9**9**9",
    "(10**100)**(10**100)",
    "2**2**2**2**2**2",
    "(" * 150 + "1" + ")" * 150,
    "-" * 200 + "1",
    "1" + "+1" * (MAX_LENGTH // 2),
    "9" * 5000,
    "1e308 * 10",
    "10.0 ** 400",
    "masspole * " + "(" * 40 + "2" + ")" * 40 + " ** 9 ** 9",
]


@pytest.mark.timeout(10)
@pytest.mark.parametrize("expression", HANGING)
def test_expressions_that_would_hang_or_overflow_are_refused_at_once(expression):
    with pytest.raises(ExpressionError) as error:
        parse_arithmetic(expression, where="[env.derived] polemass_length")
    message = str(error.value)
    assert message.startswith("[env.derived] polemass_length: ") and "\n" not in message and len(message) < 300


@pytest.mark.timeout(10)
@pytest.mark.parametrize("expression", HANGING)
def test_conditions_are_bounded_too(expression):
    with pytest.raises(ExpressionError):
        parse_condition(f"obs[0] > {expression}", where="when", names=("obs",))


@pytest.mark.timeout(30)
def test_the_space_set_line_of_the_issue_is_refused_in_one_line():
    tables, source = read_space_tables("cartpole")
    tables = merge_space_lines(tables, ['env.derived = {polemass_length = "9**9**9"}'])
    with pytest.raises(SpaceError, match=r"'9\*\*9\*\*9' cannot be computed in 64-bit floats") as error:
        build_space(tables, source=source)
    assert "[env.derived] polemass_length" in str(error.value) and "\n" not in str(error.value)


@pytest.mark.timeout(60)
def test_the_audit_command_refuses_it_in_one_line(tmp_path):
    completed = subprocess.run(
        [sys.executable, "-m", "dsage_ray.cli", "audit", "--domain", "gym", "--space", "cartpole", "--agent", "random",
         "--preset", "tiny", "--local", "--out", str(tmp_path / "audit"),
         "--space-set", 'env.derived = {polemass_length = "9**9**9"}'],
        capture_output=True, text=True, timeout=60)
    assert completed.returncode == 2, completed.stderr[-2000:]
    lines = completed.stderr.strip().splitlines()
    assert "9**9**9" in lines[-1] and "64-bit floats" in lines[-1]


@pytest.mark.timeout(10)
def test_huge_integers_in_a_space_file_are_refused_not_a_traceback(tmp_path):
    path = tmp_path / "space.toml"
    path.write_text("[env]\nid = \"CartPole-v1\"\nmax_episode_steps = " + "9" * 5000 + "\n")
    with pytest.raises(SpaceError, match="not TOML"):
        read_space_tables(str(path))
    with pytest.raises(SpaceError, match="not a line of a space file"):
        merge_space_lines({}, ["env.max_episode_steps = " + "9" * 5000])


def test_arithmetic_is_in_floats_with_names_and_subscripts():
    assert evaluate_expression("a * b + 2 ** 2 - -1", {"a": 2.0, "b": 3.0}) == 11.0
    assert evaluate_expression("state[2] * 2", {"state": np.array([0.0, 1.0, 0.25])}) == 0.5
    assert evaluate_expression("2 ** 0.5", {}) == pytest.approx(2 ** 0.5)
    with pytest.raises(KeyError):
        evaluate_expression("a + c", {"a": 1.0})
    with pytest.raises(ValueError):  # a negative number to a fractional power: no complex numbers
        evaluate_expression("a ** 0.5", {"a": -4.0})
    with pytest.raises(OverflowError):  # large values met at run time fail at once too
        evaluate_expression("a ** a", {"a": 1e6})


def test_conditions_read_observations_and_info_keys():
    contact = parse_condition("obs[6] > 0 or obs[7] > 0", where="when", names=("obs", "info", "step"))
    assert contact.holds({"obs": np.array([0, 0, 0, 0, 0, 0, 0, 1.0])})
    assert not contact.holds({"obs": np.zeros(8)})
    flagged = parse_condition('info["is_success"] and not step < 3', where="when", names=("obs", "info", "step"))
    assert flagged.holds({"info": {"is_success": True}, "step": 3})
    assert not flagged.holds({"info": {"is_success": True}, "step": 2})
    assert parse_condition("-1 < obs[0] <= 1", where="when", names=("obs",)).holds({"obs": [1.0]})


@pytest.mark.parametrize("text, message", [
    ("__import__('os')", "may hold only"),
    ("obs.shape", "may hold only"),
    ("obs[i]", "a subscript is NAME[INDEX]"),
    ("'text' == 'text'", "text is allowed only as a key"),
    ("True", "may hold only"),
    ("lambda: 1", "may hold only"),
    ("1 / 0", "cannot be computed"),
    ("(-8) ** (1 / 3)", "cannot be computed"),
    ("x" * (MAX_LENGTH + 1), f"at most {MAX_LENGTH}"),
    ("-" * (MAX_DEPTH + 1) + "1", f"more than {MAX_DEPTH} levels"),
    (3, "expected an expression as a string"),
])
def test_anything_else_is_named(text, message):
    with pytest.raises(ExpressionError, match=None) as error:
        parse_condition(text, where="when", names=("obs",))
    assert message in str(error.value) and "\n" not in str(error.value)
